#include "slam_core/solvers/relative_pose.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>

#include <opengv/relative_pose/CentralRelativeAdapter.hpp>
#include <opengv/relative_pose/methods.hpp>
#include <opengv/sac/Ransac.hpp>
#include <opengv/sac_problems/relative_pose/CentralRelativePoseSacProblem.hpp>

#include "slam_core/solvers/solver_internal.h"

namespace ccm::solvers {
namespace {

using RelativeProblem = opengv::sac_problems::relative_pose::CentralRelativePoseSacProblem;

RelativeProblem::algorithm_t ToOpenGv(RelativePoseAlgorithm a) {
  switch (a) {
    case RelativePoseAlgorithm::kStewenius5pt: return RelativeProblem::STEWENIUS;
    case RelativePoseAlgorithm::kNister5pt: return RelativeProblem::NISTER;
    case RelativePoseAlgorithm::kEightPoint: return RelativeProblem::EIGHTPT;
  }
  return RelativeProblem::STEWENIUS;
}

// OpenGV's model is cam1_from_cam2 = [R12 | t12] (pose of view 2 in view 1).
SE3 FromOpenGv(const opengv::transformation_t& T) {
  return SE3(Eigen::Matrix3d(T.leftCols<3>()), Eigen::Vector3d(T.col(3))).inverse();
}

SE3 NormalizeTranslation(const SE3& T) {
  const double n = T.translation().norm();
  return n > 0.0 ? SE3(T.rotation(), T.translation() / n) : T;
}

opengv::transformation_t ToOpenGvModel(const SE3& cam2_from_cam1) {
  const SE3 cam1_from_cam2 = cam2_from_cam1.inverse();
  opengv::transformation_t T;
  T.leftCols<3>() = cam1_from_cam2.rotation_matrix();
  T.col(3) = cam1_from_cam2.translation();
  return T;
}

// Sampson approximation of the angular distance of (f1, f2) to the epipolar constraint,
// with gradients taken on the tangent planes of the unit sphere.
double SampsonAngle(const Eigen::Matrix3d& E, const Eigen::Vector3d& f1, const Eigen::Vector3d& f2) {
  const Eigen::Vector3d ef1 = E * f1, etf2 = E.transpose() * f2;
  const Eigen::Vector3d a = ef1 - f2 * f2.dot(ef1), b = etf2 - f1 * f1.dot(etf2);
  return f2.dot(ef1) / std::sqrt(std::max(a.squaredNorm() + b.squaredNorm(), 1e-30));
}

// 5-DoF pose on SO(3) x S^2: rotation increment on the left, translation moved in the
// tangent plane of the unit sphere.
SE3 Perturb(const SE3& T, const Eigen::Matrix<double, 5, 1>& d) {
  const Eigen::Vector3d& t = T.translation();
  const Eigen::Vector3d e1 = t.unitOrthogonal(), e2 = t.cross(e1);
  Eigen::Quaterniond dq(Eigen::AngleAxisd(d.head<3>().norm(), d.head<3>().normalized()));
  if (d.head<3>().norm() < 1e-15) dq = Eigen::Quaterniond::Identity();
  return SE3(dq * T.rotation(), (t + d(3) * e1 + d(4) * e2).normalized());
}

// Cauchy loss: redescending, so a borderline outlier that slipped into the inlier set
// has almost no pull (a Huber loss still let such points bend the translation by degrees).
struct RobustCost {
  double scale;  // radians
  double Weight(double r) const { return 1.0 / (1.0 + (r * r) / (scale * scale)); }
  double Rho(double r) const { return scale * scale * std::log1p((r * r) / (scale * scale)); }
};

template <class Bearings>
double TotalCost(const SE3& T, const Bearings& f1, const Bearings& f2,
                 const std::vector<int>& idx, const RobustCost& cost) {
  const Eigen::Matrix3d E = EssentialFromPose(T);
  double c = 0.0;
  for (int i : idx) c += cost.Rho(SampsonAngle(E, f1[i], f2[i]));
  return c;
}

// Levenberg-Marquardt (IRLS weights) with a Cauchy loss and forward-difference Jacobians
// (5 parameters, cheap residuals). rotation_only keeps the translation direction fixed.
template <class Bearings>
SE3 RefineLm(const SE3& initial, const Bearings& f1, const Bearings& f2, const std::vector<int>& idx,
             double loss_scale_rad, bool rotation_only = false, int max_iterations = 100) {
  const RobustCost cost{loss_scale_rad};
  SE3 T = NormalizeTranslation(initial);
  double current = TotalCost(T, f1, f2, idx, cost), lambda = 1e-4;
  constexpr double kStep = 1e-7;
  for (int iter = 0; iter < max_iterations; ++iter) {
    Eigen::Matrix<double, 5, 5> H = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> g = Eigen::Matrix<double, 5, 1>::Zero();
    const Eigen::Matrix3d E = EssentialFromPose(T);
    std::array<Eigen::Matrix3d, 5> Ed;
    for (int k = 0; k < 5; ++k) Ed[k] = EssentialFromPose(Perturb(T, Eigen::Matrix<double, 5, 1>::Unit(k) * kStep));
    for (int i : idx) {
      const double r = SampsonAngle(E, f1[i], f2[i]);
      Eigen::Matrix<double, 5, 1> J;
      for (int k = 0; k < 5; ++k) J(k) = (SampsonAngle(Ed[k], f1[i], f2[i]) - r) / kStep;
      const double w = cost.Weight(r);
      H += w * J * J.transpose();
      g += w * J * r;
    }
    if (rotation_only) {
      H.bottomRows<2>().setZero();
      H.rightCols<2>().setZero();
      H.bottomRightCorner<2, 2>().setIdentity();
      g.tail<2>().setZero();
    }
    bool improved = false;
    for (int attempt = 0; attempt < 6 && !improved; ++attempt) {
      Eigen::Matrix<double, 5, 5> A = H;
      A.diagonal() *= 1.0 + lambda;
      const Eigen::Matrix<double, 5, 1> delta = A.ldlt().solve(-g);
      const SE3 candidate = Perturb(T, delta);
      const double c = TotalCost(candidate, f1, f2, idx, cost);
      if (std::isfinite(c) && c < current) {
        improved = true;
        const bool converged = current - c < 1e-10 * current;
        T = candidate;
        current = c;
        lambda = std::max(lambda * 0.1, 1e-10);
        if (converged) return T;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  return T;
}

// OpenGV scores every hypothesis by triangulating all points (the dominant cost at 500
// correspondences). Hypotheses are scored here with the squared Sampson angle instead,
// which needs no triangulation; cheirality is checked once at the end (FinalInliers).
class SampsonScoredProblem : public RelativeProblem {
 public:
  SampsonScoredProblem(adapter_t& adapter, algorithm_t algorithm, const opengv::bearingVectors_t& f1,
                       const opengv::bearingVectors_t& f2)
      : RelativeProblem(adapter, algorithm, false), f1_(f1), f2_(f2) {}

  void getSelectedDistancesToModel(const model_t& model, const std::vector<int>& indices,
                                   std::vector<double>& scores) const override {
    const Eigen::Matrix3d E = EssentialFromPose(FromOpenGv(model));
    for (int i : indices) {
      const double r = SampsonAngle(E, f1_[i], f2_[i]);
      scores.push_back(r * r);
    }
  }

  /// Inliers under both the Sampson test and OpenGV's triangulating residual, which
  /// compares signed rays: a point behind either camera scores ~2 and is rejected.
  std::vector<int> FinalInliers(const model_t& model, double sampson_threshold, double opengv_threshold) const {
    std::vector<int> candidates, inliers;
    std::vector<double> sampson, triangulated;
    getSelectedDistancesToModel(model, *indices_, sampson);
    for (size_t k = 0; k < sampson.size(); ++k) {
      if (sampson[k] < sampson_threshold) candidates.push_back((*indices_)[k]);
    }
    RelativeProblem::getSelectedDistancesToModel(model, candidates, triangulated);
    for (size_t k = 0; k < candidates.size(); ++k) {
      if (triangulated[k] < opengv_threshold) inliers.push_back(candidates[k]);
    }
    return inliers;
  }

 private:
  const opengv::bearingVectors_t& f1_;
  const opengv::bearingVectors_t& f2_;
};

// Refine, then re-select inliers under the refined model; a second round helps after a
// noisy minimal sample. The refined model is kept even if a few borderline points leave
// the set; only a collapse (a bad local minimum) is refused.
void RefineAndReselect(SampsonScoredProblem& problem, const opengv::bearingVectors_t& f1,
                       const opengv::bearingVectors_t& f2, double loss_scale, double threshold,
                       opengv::transformation_t* model, std::vector<int>* inliers) {
  for (int round = 0; round < 2; ++round) {
    const SE3 refined = RefineLm(FromOpenGv(*model), f1, f2, *inliers, loss_scale);
    const opengv::transformation_t refined_model = ToOpenGvModel(refined);
    std::vector<int> refined_inliers;
    problem.selectWithinDistance(refined_model, threshold, refined_inliers);
    if (refined_inliers.size() < 0.9 * inliers->size()) break;
    *model = refined_model;
    inliers->swap(refined_inliers);
  }
}

}  // namespace

std::string RelativePoseOptions::Validate() const {
  const std::string r = ransac.Validate();
  if (!r.empty()) return r;
  if (min_inliers < 5) return "min_inliers must be >= 5";
  return "";
}

Eigen::Matrix3d EssentialFromPose(const SE3& cam2_from_cam1) {
  const Eigen::Vector3d& t = cam2_from_cam1.translation();
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return tx * cam2_from_cam1.rotation_matrix();
}

MotionAmbiguity ProfileTranslationDirections(const SE3& cam2_from_cam1,
                                            const std::vector<Eigen::Vector3d>& bearings1,
                                            const std::vector<Eigen::Vector3d>& bearings2,
                                            const std::vector<int>& indices, double sigma_rad,
                                            double min_angle_deg) {
  // Cauchy loss at 2 sigma (about the 95 % gate of one degree of freedom), cost in sigma^2.
  const RobustCost cost{2.0 * sigma_rad};
  const auto cost_of = [&](const SE3& T) { return TotalCost(T, bearings1, bearings2, indices, cost) / (sigma_rad * sigma_rad); };
  const auto line_angle_deg = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::acos(std::clamp(std::abs(a.normalized().dot(b.normalized())), 0.0, 1.0)) * 180.0 / M_PI;
  };
  MotionAmbiguity out;
  // Settled under this cost first (RefineLm only takes steps that lower it).
  const SE3 chosen = RefineLm(cam2_from_cam1, bearings1, bearings2, indices, cost.scale);
  out.chosen_cost = cost_of(chosen);
  const Eigen::Vector3d t0 = chosen.translation();
  // Directions on a Fibonacci sphere; t and -t give the same essential matrix, so each
  // line is visited once. A few Gauss-Newton steps of the rotation per direction: the
  // rotation of a competing motion differs by a degree or two.
  constexpr int kDirections = 300;
  std::vector<std::pair<double, SE3>> scored;
  for (int k = 0; k < kDirections; ++k) {
    const double z = 1.0 - (k + 0.5) / kDirections;  // upper hemisphere
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = k * M_PI * (3.0 - std::sqrt(5.0));
    const Eigen::Vector3d d(r * std::cos(phi), r * std::sin(phi), z);
    if (line_angle_deg(d, t0) < min_angle_deg) continue;
    const SE3 T = RefineLm(SE3(chosen.rotation(), d), bearings1, bearings2, indices, cost.scale, true, 3);
    scored.emplace_back(cost_of(T), T);
  }
  if (scored.empty()) return out;
  const size_t keep = std::min<size_t>(3, scored.size());
  std::partial_sort(scored.begin(), scored.begin() + keep, scored.end(),
                    [](const auto& a, const auto& b) { return a.first < b.first; });
  out.rival_cost = scored.front().first;
  out.rival = scored.front().second;
  for (size_t k = 0; k < keep; ++k) {
    // Settle the best grid directions into their own minimum; one that slides back into
    // the chosen motion's valley keeps its grid cost.
    const SE3 T = RefineLm(scored[k].second, bearings1, bearings2, indices, cost.scale);
    const double c = cost_of(T);
    if (line_angle_deg(T.translation(), t0) >= min_angle_deg && c < out.rival_cost) {
      out.rival_cost = c;
      out.rival = T;
    }
  }
  out.rival_angle_deg = line_angle_deg(out.rival.translation(), t0);
  return out;
}

SE3 RefineRelativePose(const SE3& cam2_from_cam1, const std::vector<Eigen::Vector3d>& bearings1,
                       const std::vector<Eigen::Vector3d>& bearings2, const std::vector<int>& indices,
                       double loss_scale_rad) {
  return RefineLm(cam2_from_cam1, bearings1, bearings2, indices, loss_scale_rad);
}

RelativePoseResult EstimateRelativePose(const std::vector<Eigen::Vector3d>& bearings1,
                                        const std::vector<Eigen::Vector3d>& bearings2,
                                        const RelativePoseOptions& options) {
  RelativePoseResult result;
  result.message = options.Validate();
  if (!result.message.empty()) return result;
  if (bearings1.size() != bearings2.size()) {
    result.message = "bearing vectors differ in size";
    return result;
  }
  const int n = static_cast<int>(bearings1.size());
  result.inliers.assign(n, false);
  const opengv::bearingVectors_t f1 = internal::ToOpenGv(bearings1);
  const opengv::bearingVectors_t f2 = internal::ToOpenGv(bearings2);
  opengv::relative_pose::CentralRelativeAdapter adapter(f1, f2);
  auto problem = std::make_shared<SampsonScoredProblem>(adapter, ToOpenGv(options.algorithm), f1, f2);
  const int needed = std::max(problem->getSampleSize(), options.min_inliers);
  if (n < needed) {
    result.status = SolverStatus::kTooFewPoints;
    result.message = "need at least " + std::to_string(needed) + " correspondences, got " + std::to_string(n);
    return result;
  }
  internal::SeedOpenGvProblem(problem.get(), options.ransac.seed);

  opengv::sac::Ransac<SampsonScoredProblem> ransac;
  ransac.sac_model_ = problem;
  // Squared Sampson angle ~ a1^2 + a2^2 over the two views: both within theta -> 2 theta^2.
  const double theta = options.ransac.ThresholdAngleRad();
  ransac.threshold_ = 2.0 * theta * theta;
  // OpenGV residual = sum over both views of (1 - cos(angle)).
  const double opengv_threshold = 2.0 * internal::OneMinusCos(theta);
  ransac.max_iterations_ = options.ransac.max_iterations;
  ransac.probability_ = options.ransac.confidence;
  if (!ransac.computeModel(0)) {
    result.status = SolverStatus::kRansacFailed;
    result.message = "no essential-matrix hypothesis";
    return result;
  }
  result.iterations = ransac.iterations_;
  opengv::transformation_t model = ransac.model_coefficients_;
  std::vector<int> inliers = ransac.inliers_;
  if (options.refine && static_cast<int>(inliers.size()) >= options.min_inliers) {
    RefineAndReselect(*problem, f1, f2, 0.5 * theta, ransac.threshold_, &model, &inliers);
  }
  inliers = problem->FinalInliers(model, ransac.threshold_, opengv_threshold);
  result.cam2_from_cam1 = NormalizeTranslation(FromOpenGv(model));
  for (int i : inliers) result.inliers[i] = true;
  result.num_inliers = static_cast<int>(inliers.size());
  if (result.num_inliers < options.min_inliers) {
    result.status = SolverStatus::kTooFewInliers;
    result.message = std::to_string(result.num_inliers) + " inliers < min_inliers " +
                     std::to_string(options.min_inliers);
    return result;
  }
  result.status = SolverStatus::kOk;
  return result;
}

}  // namespace ccm::solvers
