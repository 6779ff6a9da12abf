#include "slam_core/solvers/similarity.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <random>

#include "slam_core/solvers/solver_internal.h"

namespace ccm::solvers {
namespace {

constexpr int kSimilaritySample = 3;

// Inlier test of one correspondence under b_from_a (and its precomputed inverse).
bool IsInlier(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Sim3& b_from_a,
              const Sim3& a_from_b, const Sim3Options& options, double max_angle_rad) {
  const Eigen::Vector3d a_in_b = b_from_a * a;
  const Eigen::Vector3d b_in_a = a_from_b * b;
  if (options.metric == Sim3InlierMetric::kAngular) {
    return internal::AngleBetween(a_in_b, b) <= max_angle_rad &&
           internal::AngleBetween(b_in_a, a) <= max_angle_rad;
  }
  const double r = options.max_relative_distance;
  return (a_in_b - b).norm() <= r * b.norm() && (b_in_a - a).norm() <= r * a.norm();
}

int ScoreModel(const std::vector<Eigen::Vector3d>& pa, const std::vector<Eigen::Vector3d>& pb,
               const Sim3& b_from_a, const Sim3Options& options, double max_angle_rad,
               std::vector<bool>* mask) {
  const Sim3 a_from_b = b_from_a.inverse();
  mask->assign(pa.size(), false);
  int count = 0;
  for (size_t i = 0; i < pa.size(); ++i) {
    if (IsInlier(pa[i], pb[i], b_from_a, a_from_b, options, max_angle_rad)) {
      (*mask)[i] = true;
      ++count;
    }
  }
  return count;
}

// Seeded adaptive RANSAC over 3-point samples; returns the best inlier count (-1 if
// every sample was degenerate).
int RunRansac(const std::vector<Eigen::Vector3d>& pa, const std::vector<Eigen::Vector3d>& pb,
              const Sim3Options& options, double max_angle, Sim3* best, std::vector<bool>* best_mask,
              int* iterations) {
  const int n = static_cast<int>(pa.size());
  std::mt19937_64 rng(options.ransac.seed);
  std::vector<int> scratch, sample;
  std::vector<bool> mask;
  int best_count = -1, needed = options.ransac.max_iterations, it = 0;
  for (; it < needed; ++it) {
    internal::DrawSample(n, kSimilaritySample, &rng, &scratch, &sample);
    const std::optional<Sim3> S = AlignUmeyama(pa, pb, options.fix_scale, sample);
    if (!S) continue;
    const int count = ScoreModel(pa, pb, *S, options, max_angle, &mask);
    if (count > best_count) {
      best_count = count;
      *best = *S;
      *best_mask = mask;
      needed = internal::AdaptiveIterations(double(count) / n, kSimilaritySample, options.ransac.confidence,
                                            options.ransac.max_iterations);
    }
  }
  *iterations = it;
  return best_count;
}

}  // namespace

std::optional<Sim3> AlignUmeyama(const std::vector<Eigen::Vector3d>& points_a,
                                 const std::vector<Eigen::Vector3d>& points_b, bool fix_scale,
                                 const std::vector<int>& indices) {
  const int n = indices.empty() ? static_cast<int>(points_a.size()) : static_cast<int>(indices.size());
  if (n < 3 || points_a.size() != points_b.size()) return std::nullopt;
  Eigen::Matrix3Xd A(3, n), B(3, n);
  for (int k = 0; k < n; ++k) {
    const int i = indices.empty() ? k : indices[k];
    A.col(k) = points_a[i];
    B.col(k) = points_b[i];
  }
  // Reject collinear / coincident sets: the second singular value of the centred cloud
  // must not vanish relative to the first, or the rotation about the line is free. The
  // singular values squared are the eigenvalues of its 3x3 scatter matrix (ascending); a
  // fixed-size solver, because Eigen's SVD of a 3xN matrix costs ~8 s of compile time.
  const Eigen::Matrix3Xd Ac = A.colwise() - A.rowwise().mean();
  const Eigen::Vector3d sv2 = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(Ac * Ac.transpose()).eigenvalues();
  if (!(sv2(2) > 1e-24) || sv2(1) < 1e-12 * sv2(2)) return std::nullopt;
  const Eigen::Matrix4d T = Eigen::umeyama(A, B, !fix_scale);
  if (!T.allFinite()) return std::nullopt;
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  const double s = std::cbrt(sR.determinant());
  if (!(s > 0.0)) return std::nullopt;
  return Sim3(s, Eigen::Quaterniond(Eigen::Matrix3d(sR / s)), T.topRightCorner<3, 1>());
}

std::string Sim3Options::Validate() const {
  const std::string r = ransac.Validate();
  if (metric == Sim3InlierMetric::kAngular && !r.empty()) return r;
  if (ransac.max_iterations < 1 || !(ransac.confidence > 0.0 && ransac.confidence < 1.0)) {
    return "ransac.max_iterations >= 1 and ransac.confidence in (0, 1) required";
  }
  if (!(max_relative_distance > 0.0)) return "max_relative_distance must be > 0";
  if (min_inliers < 3) return "min_inliers must be >= 3";
  return "";
}

Sim3Result EstimateSim3(const std::vector<Eigen::Vector3d>& points_a,
                        const std::vector<Eigen::Vector3d>& points_b, const Sim3Options& options) {
  Sim3Result result;
  result.message = options.Validate();
  if (!result.message.empty()) return result;
  if (points_a.size() != points_b.size()) {
    result.message = "point sets differ in size";
    return result;
  }
  const int n = static_cast<int>(points_a.size());
  result.inliers.assign(n, false);
  if (n < std::max(kSimilaritySample, options.min_inliers)) {
    result.status = SolverStatus::kTooFewPoints;
    result.message = "need at least " + std::to_string(std::max(kSimilaritySample, options.min_inliers)) +
                     " correspondences, got " + std::to_string(n);
    return result;
  }
  const double max_angle = options.metric == Sim3InlierMetric::kAngular ? options.ransac.ThresholdAngleRad() : 0.0;
  Sim3 best;
  int it = 0;
  int best_count = RunRansac(points_a, points_b, options, max_angle, &best, &result.inliers, &it);
  std::vector<bool> mask;
  result.iterations = it;
  if (best_count < kSimilaritySample) {
    result.status = best_count < 0 ? SolverStatus::kDegenerate : SolverStatus::kTooFewInliers;
    result.message = best_count < 0 ? "all samples degenerate" : "no consensus";
    return result;
  }
  for (int round = 0; options.refine && round < 3; ++round) {
    const std::optional<Sim3> S = AlignUmeyama(points_a, points_b, options.fix_scale, internal::MaskToIndices(result.inliers));
    if (!S) break;
    const int count = ScoreModel(points_a, points_b, *S, options, max_angle, &mask);
    if (count < 0.9 * best_count) break;  // keep the least-squares model unless it collapses
    best_count = count;
    best = *S;
    result.inliers = mask;
  }
  result.b_from_a = best;
  result.num_inliers = best_count;
  if (best_count < options.min_inliers) {
    result.status = SolverStatus::kTooFewInliers;
    result.message = std::to_string(best_count) + " inliers < min_inliers " + std::to_string(options.min_inliers);
    return result;
  }
  result.status = SolverStatus::kOk;
  return result;
}

}  // namespace ccm::solvers
