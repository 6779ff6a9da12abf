#include "slam_core/place_recognition/sim3_refinement.h"

#include <ceres/ceres.h>

namespace ccm {

namespace {

// Residual of one match in one image: `point` (in the other view's frame) mapped by
// Exp(xi) * base (or its inverse) and projected, minus the observed keypoint, over sigma.
struct ReprojectionResidual {
  const CameraModel* camera;
  Eigen::Vector3d point;
  Eigen::Vector2d observed;
  double inv_sigma;
  Sim3 base;
  bool inverse;

  bool operator()(const double* xi, double* residual) const {
    const Sim3 s = Sim3::Exp(Eigen::Map<const Eigen::Matrix<double, 7, 1>>(xi)) * base;
    const Eigen::Vector3d p = inverse ? s.inverse() * point : s * point;
    Eigen::Vector2d uv;
    if (p.z() <= 0.0 || !camera->ProjectForCost(p, &uv)) return false;
    residual[0] = (uv.x() - observed.x()) * inv_sigma;
    residual[1] = (uv.y() - observed.y()) * inv_sigma;
    return true;
  }
  double SquaredError(const Sim3& s) const {
    double r[2];
    const double zero[7] = {0, 0, 0, 0, 0, 0, 0};
    ReprojectionResidual copy = *this;
    copy.base = s;
    if (!copy(zero, r)) return 1e12;
    return r[0] * r[0] + r[1] * r[1];
  }
};

ReprojectionResidual MakeResidual(const VerificationView& observer, int keypoint, const Eigen::Vector3d& point,
                                  const Sim3& base, bool inverse) {
  const Keypoint& kp = observer.features.keypoints[keypoint];
  return ReprojectionResidual{observer.camera.get(), point, Eigen::Vector2d(kp.u, kp.v),
                              1.0 / observer.pyramid.scale[kp.level], base, inverse};
}

// One optimisation over the active matches; returns false if Ceres could not run.
bool Optimize(const std::vector<ReprojectionResidual>& forward, const std::vector<ReprojectionResidual>& backward,
              const std::vector<bool>& active, const Sim3RefineOptions& options, Sim3* s) {
  double xi[7] = {0, 0, 0, 0, 0, 0, 0};
  ceres::Problem problem;
  int blocks = 0;
  for (std::size_t k = 0; k < forward.size(); ++k) {
    if (!active[k]) continue;
    for (const ReprojectionResidual* r : {&forward[k], &backward[k]}) {
      ReprojectionResidual res = *r;
      res.base = *s;
      problem.AddResidualBlock(
          new ceres::NumericDiffCostFunction<ReprojectionResidual, ceres::FORWARD, 2, 7>(
              new ReprojectionResidual(res)),
          new ceres::HuberLoss(options.huber_px), xi);
      ++blocks;
    }
  }
  if (blocks < 6) return false;
  ceres::Solver::Options solver;
  solver.max_num_iterations = options.max_iterations;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  if (!summary.IsSolutionUsable()) return false;
  *s = Sim3::Exp(Eigen::Map<const Eigen::Matrix<double, 7, 1>>(xi)) * *s;
  return true;
}

}  // namespace

std::string Sim3RefineOptions::Validate() const {
  if (max_iterations < 1) return "max_iterations must be >= 1";
  if (!(huber_px > 0.0) || !(inlier_chi2 > 0.0)) return "huber_px and inlier_chi2 must be > 0";
  if (rounds < 1) return "rounds must be >= 1";
  return {};
}

Sim3RefineResult RefineSim3(const VerificationView& candidate, const VerificationView& query,
                            const std::vector<FeatureMatch>& matches, const Sim3& initial,
                            const Sim3RefineOptions& options) {
  Sim3RefineResult result;
  result.query_from_candidate = initial;
  result.inliers.assign(matches.size(), false);
  std::vector<ReprojectionResidual> forward, backward;
  std::vector<int> match_of;
  for (int k = 0; k < static_cast<int>(matches.size()); ++k) {
    const FeatureMatch& m = matches[k];
    if (!candidate.HasPoint(m.index1) || !query.HasPoint(m.index2)) continue;
    ReprojectionResidual f = MakeResidual(query, m.index2, candidate.points_cam[m.index1], initial, false);
    ReprojectionResidual b = MakeResidual(candidate, m.index1, query.points_cam[m.index2], initial, true);
    // Matches that cannot be projected at the start would stall the solver: leave them out.
    if (f.SquaredError(initial) >= 1e12 || b.SquaredError(initial) >= 1e12) continue;
    forward.push_back(f);
    backward.push_back(b);
    match_of.push_back(k);
  }
  std::vector<bool> active(forward.size(), true);
  Sim3 s = initial;
  for (int round = 0; round < options.rounds; ++round) {
    if (!Optimize(forward, backward, active, options, &s)) return result;
    for (std::size_t k = 0; k < forward.size(); ++k) {
      active[k] = forward[k].SquaredError(s) < options.inlier_chi2 &&
                  backward[k].SquaredError(s) < options.inlier_chi2;
    }
  }
  result.ok = true;
  result.query_from_candidate = s;
  for (std::size_t k = 0; k < forward.size(); ++k) {
    result.inliers[match_of[k]] = active[k];
    result.num_inliers += active[k] ? 1 : 0;
  }
  return result;
}

}  // namespace ccm
