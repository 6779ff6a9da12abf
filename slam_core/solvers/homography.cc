#include "slam_core/solvers/homography.h"

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <random>

#include "slam_core/solvers/solver_internal.h"

namespace ccm::solvers {
namespace {

constexpr int kHomographySample = 4;
constexpr double kHugeError = 1e12;

// Hartley normalization: centroid to origin, mean distance sqrt(2).
Eigen::Matrix3d NormalizingTransform(const std::vector<Eigen::Vector2d>& x, const std::vector<int>& idx) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (int i : idx) c += x[i];
  c /= double(idx.size());
  double d = 0.0;
  for (int i : idx) d += (x[i] - c).norm();
  d /= double(idx.size());
  const double s = d > 1e-12 ? std::sqrt(2.0) / d : 1.0;
  Eigen::Matrix3d T;
  T << s, 0, -s * c.x(), 0, s, -s * c.y(), 0, 0, 1;
  return T;
}

// Normalized DLT over the selected correspondences; false if degenerate.
bool SolveDlt(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2,
              const std::vector<int>& idx, Eigen::Matrix3d* H) {
  const Eigen::Matrix3d T1 = NormalizingTransform(x1, idx), T2 = NormalizingTransform(x2, idx);
  Eigen::MatrixXd A(2 * idx.size(), 9);
  for (size_t k = 0; k < idx.size(); ++k) {
    const Eigen::Vector3d p = T1 * x1[idx[k]].homogeneous();
    const Eigen::Vector3d q = T2 * x2[idx[k]].homogeneous();
    A.row(2 * k) << 0, 0, 0, -q.z() * p.transpose(), q.y() * p.transpose();
    A.row(2 * k + 1) << q.z() * p.transpose(), 0, 0, 0, -q.x() * p.transpose();
  }
  Eigen::Matrix<double, 9, 1> h;
  if (idx.size() == kHomographySample) {
    // The 8x9 system padded with a zero row: the square fixed-size SVD has the same singular
    // values (plus a zero) and null vector, and compiles in a fifth of the dynamic one's time.
    Eigen::Matrix<double, 9, 9> square = Eigen::Matrix<double, 9, 9>::Zero();
    square.topRows<2 * kHomographySample>() = A;
    const Eigen::JacobiSVD<Eigen::Matrix<double, 9, 9>> svd(square, Eigen::ComputeFullV);
    if (svd.singularValues()(7) < 1e-9 * svd.singularValues()(0)) return false;
    h = svd.matrixV().col(8);
  } else {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig(A.transpose() * A);
    h = eig.eigenvectors().col(0);
  }
  const Eigen::Matrix3d Hn = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(h.data());
  *H = T2.inverse() * Hn * T1;
  const double norm = H->norm();
  if (!(norm > 0.0) || !H->allFinite()) return false;
  *H /= norm;
  return true;
}

// Symmetric test: both transfer errors within the threshold (normalized-plane units).
int ScoreHomography(const Eigen::Matrix3d& H, const std::vector<Eigen::Vector2d>& x1,
                    const std::vector<Eigen::Vector2d>& x2, const std::vector<bool>& valid,
                    double threshold, std::vector<bool>* mask) {
  const Eigen::Matrix3d Hinv = H.inverse();
  mask->assign(x1.size(), false);
  int count = 0;
  for (size_t i = 0; i < x1.size(); ++i) {
    if (!valid[i]) continue;
    if (HomographyTransferError(H, x1[i], x2[i]) <= threshold &&
        HomographyTransferError(Hinv, x2[i], x1[i]) <= threshold) {
      (*mask)[i] = true;
      ++count;
    }
  }
  return count;
}

struct PlaneData {
  std::vector<Eigen::Vector2d> x1, x2;  // normalized image planes
  std::vector<bool> valid;              // both bearings point forward
  std::vector<int> valid_idx;
};

PlaneData ToNormalizedPlanes(const std::vector<Eigen::Vector3d>& b1, const std::vector<Eigen::Vector3d>& b2) {
  PlaneData d;
  const size_t n = b1.size();
  d.x1.resize(n);
  d.x2.resize(n);
  d.valid.assign(n, false);
  for (size_t i = 0; i < n; ++i) {
    if (b1[i].z() <= 1e-6 || b2[i].z() <= 1e-6) continue;  // no normalized plane
    d.x1[i] = b1[i].head<2>() / b1[i].z();
    d.x2[i] = b2[i].head<2>() / b2[i].z();
    d.valid[i] = true;
    d.valid_idx.push_back(static_cast<int>(i));
  }
  return d;
}

// Seeded adaptive RANSAC over the forward-facing correspondences; returns the best
// inlier count (-1 if every sample was degenerate).
int RunRansac(const PlaneData& d, double threshold, const RansacOptions& ro, Eigen::Matrix3d* best_h,
              std::vector<bool>* best_mask, int* iterations) {
  const int nv = static_cast<int>(d.valid_idx.size());
  std::mt19937_64 rng(ro.seed);
  std::vector<int> scratch, sample(kHomographySample);
  std::vector<bool> mask;
  int best_count = -1, needed = ro.max_iterations, it = 0;
  for (; it < needed; ++it) {
    internal::DrawSample(nv, kHomographySample, &rng, &scratch, &sample);
    for (int& s : sample) s = d.valid_idx[s];
    Eigen::Matrix3d H;
    if (!SolveDlt(d.x1, d.x2, sample, &H)) continue;
    const int count = ScoreHomography(H, d.x1, d.x2, d.valid, threshold, &mask);
    if (count > best_count) {
      best_count = count;
      *best_h = H;
      *best_mask = mask;
      needed = internal::AdaptiveIterations(double(count) / nv, kHomographySample, ro.confidence, ro.max_iterations);
    }
  }
  *iterations = it;
  return best_count;
}

}  // namespace

std::string HomographyOptions::Validate() const {
  const std::string r = ransac.Validate();
  if (!r.empty()) return r;
  if (min_inliers < kHomographySample) return "min_inliers must be >= 4";
  return "";
}

double HomographyTransferError(const Eigen::Matrix3d& H, const Eigen::Vector2d& x1, const Eigen::Vector2d& x2) {
  const Eigen::Vector3d p = H * x1.homogeneous();
  if (std::abs(p.z()) < 1e-12) return kHugeError;
  return (p.head<2>() / p.z() - x2).norm();
}

HomographyResult EstimateHomography(const std::vector<Eigen::Vector3d>& bearings1,
                                    const std::vector<Eigen::Vector3d>& bearings2,
                                    const HomographyOptions& options) {
  HomographyResult result;
  result.message = options.Validate();
  if (!result.message.empty()) return result;
  if (bearings1.size() != bearings2.size()) {
    result.message = "bearing vectors differ in size";
    return result;
  }
  const int n = static_cast<int>(bearings1.size());
  result.inliers.assign(n, false);
  const PlaneData d = ToNormalizedPlanes(bearings1, bearings2);
  const std::vector<Eigen::Vector2d>&x1 = d.x1, &x2 = d.x2;
  const std::vector<bool>& valid = d.valid;
  const int nv = static_cast<int>(d.valid_idx.size());
  if (nv < std::max(kHomographySample, options.min_inliers)) {
    result.status = SolverStatus::kTooFewPoints;
    result.message = std::to_string(nv) + " forward-facing correspondences are too few";
    return result;
  }
  // Transfer error on the normalized plane: pixels / focal.
  const double threshold = options.ransac.threshold_px / options.ransac.focal_px;
  int it = 0;
  int best_count = RunRansac(d, threshold, options.ransac, &result.cam2_H_cam1, &result.inliers, &it);
  std::vector<bool> mask;
  result.iterations = it;
  if (best_count < kHomographySample) {
    result.status = SolverStatus::kRansacFailed;
    result.message = "no homography hypothesis";
    return result;
  }
  for (int round = 0; round < 2; ++round) {
    Eigen::Matrix3d H;
    if (!SolveDlt(x1, x2, internal::MaskToIndices(result.inliers), &H)) break;
    const int count = ScoreHomography(H, x1, x2, valid, threshold, &mask);
    if (count < 0.9 * best_count) break;  // keep the least-squares model unless it collapses
    best_count = count;
    result.cam2_H_cam1 = H;
    result.inliers = mask;
  }
  result.num_inliers = best_count;
  if (best_count < options.min_inliers) {
    result.status = SolverStatus::kTooFewInliers;
    result.message = std::to_string(best_count) + " inliers < min_inliers " + std::to_string(options.min_inliers);
    return result;
  }
  result.status = SolverStatus::kOk;
  return result;
}

std::vector<HomographyMotion> DecomposeHomography(const Eigen::Matrix3d& cam2_H_cam1) {
  // H is known up to scale including sign; R + t n^T of two cameras on the same side of
  // the plane has a positive determinant, and the decomposition needs that sign.
  const Eigen::Matrix3d Hs = cam2_H_cam1.determinant() < 0.0 ? Eigen::Matrix3d(-cam2_H_cam1) : cam2_H_cam1;
  cv::Mat H, K = cv::Mat::eye(3, 3, CV_64F);
  cv::eigen2cv(Hs, H);
  std::vector<cv::Mat> rotations, translations, normals;
  cv::decomposeHomographyMat(H, K, rotations, translations, normals);
  std::vector<HomographyMotion> motions;
  for (size_t i = 0; i < rotations.size(); ++i) {
    Eigen::Matrix3d R;
    Eigen::Vector3d t, nrm;
    cv::cv2eigen(rotations[i], R);
    cv::cv2eigen(translations[i], t);
    cv::cv2eigen(normals[i], nrm);
    if (!R.allFinite() || !t.allFinite()) continue;
    motions.push_back({SE3(R, t), nrm});
  }
  return motions;
}

}  // namespace ccm::solvers
