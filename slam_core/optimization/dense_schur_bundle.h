// One Levenberg-Marquardt pass of bundle adjustment over free 3D points and up to a few dozen
// free poses, written out instead of a ceres::Problem (internal to bundle_adjustment.cc).
// Why: the agent's local BA (a window of ~10-20 keyframes, a few thousand points) spent more
// of its time in building, preprocessing and evaluating a ceres::Problem than in the
// algebra itself; it was the largest share of the agent's CPU (docs/deployment.md
// "Footprint by thread"). This is the same problem solved the same way as Ceres' DENSE_SCHUR
// trust-region LM: same residuals, Huber weighting (Ceres' correction is the weight rho' for
// Huber), Jacobi-scaled variables with the diagonal LM damping clamped like Ceres', Nielsen's
// radius update and Ceres' stopping tolerances, so it reaches the same minimum
// (dense_schur_bundle_test compares the two). The scaling matters: without it a point of tiny
// block (gross outliers under small Huber weights) made every step of a pass fail.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slam_core/optimization/bundle_problem.h"
#include "slam_core/optimization/pose_manifold.h"

namespace ccm::opt::internal {

struct BundlePassResult {
  bool usable = false;  ///< false: the initial point could not be evaluated; variables unchanged
  double initial_cost = 0.0, final_cost = 0.0;
  int iterations = 0;            ///< steps tried (taken or not), as Ceres counts them
  int unsuccessful_steps = 0;
  std::string message;
};

/// The variables of a pass: cam_from_world blocks (quaternion x y z w, translation) and world
/// points, both updated in place. Poses marked fixed and points marked fixed in the problem do
/// not move; `scale_gauge_pose` (if >= 0) keeps translation component `scale_gauge_axis`.
struct BundlePassVariables {
  std::vector<Se3Block>* cam_from_world = nullptr;
  std::vector<Eigen::Vector3d>* points_w = nullptr;
  const std::vector<bool>* pose_fixed = nullptr;
  int scale_gauge_pose = -1;
  int scale_gauge_axis = 0;
};

struct BundlePassOptions {
  double huber_delta = 0.0;  ///< whitened units; 0: plain least squares
  int max_iterations = 10;
  double function_tolerance = 1e-6;
  double initial_trust_region_radius = 1e4;
  const std::atomic<bool>* abort = nullptr;  ///< checked between iterations
};

/// Number of poses that would be free in a pass over the `active` observations.
int CountFreePoses(const BundleProblem& problem, const std::vector<bool>& active, const std::vector<bool>& pose_fixed);

/// Runs the pass over the observations flagged in `active` (all of them of free-XYZ points:
/// the caller keeps inverse-depth points for Ceres).
BundlePassResult RunDenseSchurPass(const BundleProblem& problem, const std::vector<bool>& active,
                                   const BundlePassOptions& options, const BundlePassVariables& v);

}  // namespace ccm::opt::internal
