// Pose-only optimization (declared in bundle_adjustment.h).
#include <algorithm>
#include <chrono>
#include <memory>

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/optimization/pose_manifold.h"
#include "slam_core/optimization/reprojection_cost_analytic.h"

namespace ccm::opt {
namespace {

ceres::Solver::Summary RunPosePass(const CameraModel& camera, const std::vector<PointObservation>& obs,
                                   const std::vector<bool>& active, bool robust,
                                   const PoseOptimizerOptions& options, Se3Block* cam_from_world) {
  ceres::Problem cp;  // takes ownership of costs, loss and manifold
  ceres::LossFunction* loss = robust ? new ceres::HuberLoss(options.huber_delta) : nullptr;
  for (size_t i = 0; i < obs.size(); ++i) {
    if (!active[i]) continue;
    cp.AddResidualBlock(PoseOnlyCostAnalytic::Create(&camera, obs[i].point_w, obs[i].uv_px, obs[i].sigma_px),
                        loss, cam_from_world->data());
  }
  ceres::Solver::Summary summary;
  if (cp.NumResidualBlocks() == 0) {
    delete loss;
    return summary;
  }
  cp.SetManifold(cam_from_world->data(), NewSe3Manifold());
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.iterations_per_round;
  so.num_threads = 1;
  // A trust-region step may carry a point behind the camera; the cost then fails to
  // evaluate and Ceres treats the step as infinitely bad and shrinks it (correct), but
  // would log a warning each time: hundreds per flight.
  so.logging_type = ceres::SILENT;
  ceres::Solve(so, &cp, &summary);
  return summary;
}

// chi2 of every observation at the pose; unprojectable ones are outliers.
}  // namespace

int ClassifyObservations(const CameraModel& camera, const std::vector<PointObservation>& obs, const SE3& cam_from_world,
             double chi2_threshold, std::vector<bool>* inlier) {
  int n = 0;
  for (size_t i = 0; i < obs.size(); ++i) {
    Eigen::Vector2d uv;
    const bool ok = camera.Project(cam_from_world * obs[i].point_w, &uv) &&
                    (uv - obs[i].uv_px).squaredNorm() <= chi2_threshold * obs[i].sigma_px * obs[i].sigma_px;
    (*inlier)[i] = ok;
    n += ok ? 1 : 0;
  }
  return n;
}

std::string PoseOptimizerOptions::Validate() const {
  if (num_rounds < 1 || iterations_per_round < 1) return "num_rounds and iterations_per_round must be >= 1";
  if (!(chi2_threshold > 0.0)) return "chi2_threshold must be > 0";
  if (!(huber_delta > 0.0)) return "huber_delta must be > 0";
  if (min_inliers < 3) return "min_inliers must be >= 3 (a pose has 6 dof)";
  return "";
}

OptimizationSummary OptimizePose(const CameraModel& camera, const std::vector<PointObservation>& observations,
                                 SE3* world_from_cam, const PoseOptimizerOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  OptimizationSummary out;
  out.message = options.Validate();
  if (!out.message.empty()) return out;
  Se3Block pose = PackSe3(world_from_cam->inverse());
  // Like ORB-SLAM, every observation starts as an inlier (unless it cannot be projected).
  std::vector<bool> active(observations.size(), false);
  for (size_t i = 0; i < observations.size(); ++i) {
    Eigen::Vector2d uv;
    active[i] = camera.Project(world_from_cam->inverse() * observations[i].point_w, &uv);
  }
  int num_active = static_cast<int>(std::count(active.begin(), active.end(), true));
  bool ok = true;
  for (int round = 0; round < options.num_rounds && num_active >= options.min_inliers; ++round) {
    const bool robust = round + 1 < options.num_rounds;
    const ceres::Solver::Summary s = RunPosePass(camera, observations, active, robust, options, &pose);
    if (!s.IsSolutionUsable()) {
      ok = false;
      out.message = s.BriefReport();
      break;
    }
    if (round == 0) out.initial_cost = s.initial_cost;
    out.final_cost = s.final_cost;
    out.iterations += std::max(0, static_cast<int>(s.iterations.size()) - 1);
    out.message = s.BriefReport();
    const std::vector<bool> before = active;
    num_active = ClassifyObservations(camera, observations, UnpackSe3(pose), options.chi2_threshold, &active);
    // Classification converged: further robust rounds would repeat this one exactly, so go
    // straight to the final (non-robust) round. Saves up to two solves per tracked frame.
    if (active == before && round + 2 < options.num_rounds) round = options.num_rounds - 2;
  }
  out.inlier = active;
  out.num_inliers = num_active;
  out.usable = ok && num_active >= options.min_inliers;
  if (out.usable) {
    *world_from_cam = UnpackSe3(pose).inverse();
  } else if (out.message.empty() || ok) {
    out.message = "too few inliers: " + std::to_string(num_active);
  }
  out.solve_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace ccm::opt
