// Reprojection-error optimizers: pose-only (tracking), local BA (keyframe window with a
// fixed periphery) and global BA (whole map), on Ceres or, for the small problems solved
// per frame or keyframe, on Levenberg-Marquardt loops of our own with the same minimum. All
// are synchronous, use no threads except the num_threads Ceres workers the caller allows,
// print nothing, and update their input in place. Any ccm::CameraModel works (see reprojection_cost.h).
//
//   opt::BundleProblem problem = ...;               // copied out of the map by the caller
//   opt::OptimizationSummary s = opt::LocalBundleAdjustment(&problem, {});
//   // write poses/points back; erase observations with !s.inlier[i]
#pragma once

#include <atomic>

#include <cmath>
#include <string>
#include <vector>

#include "slam_core/optimization/bundle_problem.h"

namespace ccm::opt {

/// Pose-only optimization, ORB-SLAM style: `num_rounds` rounds of `iterations_per_round`
/// Levenberg-Marquardt iterations; after each round every observation (including earlier
/// outliers, which may come back) is classified by chi2 against the threshold, and the next
/// round uses only inliers. The robust loss is dropped in the last round.
struct PoseOptimizerOptions {
  int num_rounds = 4;
  int iterations_per_round = 10;
  double chi2_threshold = kChi2Mono2Dof;  ///< on squared whitened error (px^2 / sigma^2)
  double huber_delta = 2.447;             ///< whitened units; sqrt(5.991)
  int min_inliers = 3;                    ///< below this the result is not usable
  std::string Validate() const;
};

/// A known 3D point and its keypoint in the frame being optimized.
struct PointObservation {
  Eigen::Vector3d point_w = Eigen::Vector3d::Zero();
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double sigma_px = 1.0;
};

/// Refines *world_from_cam (initial guess in, result out) from fixed points. summary.inlier
/// flags each observation; usable is false (and the pose unchanged) if fewer than
/// min_inliers remain or the input is empty.
OptimizationSummary OptimizePose(const CameraModel& camera,
                                 const std::vector<PointObservation>& observations,
                                 SE3* world_from_cam, const PoseOptimizerOptions& options = {});

/// Flags each observation as an inlier (projects, chi2 within the threshold) at a given
/// pose without moving it; returns how many are.
int ClassifyObservations(const CameraModel& camera, const std::vector<PointObservation>& observations,
                         const SE3& cam_from_world, double chi2_threshold, std::vector<bool>* inlier);

/// kAuto: up to kDenseSchurMaxFreePoses free poses (local BA windows) our own dense-Schur
/// Levenberg-Marquardt (dense_schur_bundle.h: the same minimum as Ceres' DENSE_SCHUR, without
/// a ceres::Problem; Ceres' DENSE_SCHUR when inverse-depth points take part), else Ceres'
/// SPARSE_SCHUR (SuiteSparse when Ceres has it, else Eigen's sparse Cholesky). The others
/// always use Ceres with that linear solver.
enum class BaLinearSolver { kAuto, kSparseSchur, kIterativeSchur, kDenseSchur };
inline constexpr int kDenseSchurMaxFreePoses = 40;
/// "auto", "sparse", "iterative", "dense" (benchmarks' and configs' spelling).
const char* BaLinearSolverName(BaLinearSolver solver);
/// The solver of that name; false for an unknown name.
bool ParseBaLinearSolver(const std::string& name, BaLinearSolver* solver);

/// Shared by local and global BA. Pass 1 runs `robust_iterations` with a Huber loss. If
/// reject_outliers, observations with chi2 > threshold (or unprojectable) are dropped and
/// pass 2 runs `refine_iterations` without robust loss (ORB-SLAM's local BA). Finally all
/// observations are flagged by chi2.
struct BundleAdjusterOptions {
  int robust_iterations = 5;
  int refine_iterations = 10;
  bool reject_outliers = true;
  double chi2_threshold = kChi2Mono2Dof;
  double huber_delta = 2.447;  ///< whitened units; sqrt(5.991)
  int num_threads = 1;         ///< Ceres worker threads (Jacobians, Schur elimination)
  BaLinearSolver linear_solver = BaLinearSolver::kAuto;
  /// Gauge: if no pose in the problem is fixed, fix the first observed pose.
  bool fix_first_pose_if_none_fixed = true;
  /// Monocular scale gauge: if exactly one observed pose and no point is fixed, hold one translation
  /// component of the pose farthest from it (the one that changes most under scaling).
  /// Without it the free scale direction makes near-Gauss-Newton steps wander.
  bool fix_scale_if_one_pose_fixed = true;
  double function_tolerance = 1e-6;  ///< relative cost change that stops a pass
  /// Initial Levenberg-Marquardt trust region (Ceres' default is 1e4). Measured iterations
  /// (40-KF map perturbed 1 deg/5 cm; same map 3 deg/30 cm; 400-KF map): 1e4: 5/13/10,
  /// 1e6: 4/14/5, 1e8: 4/28/4. Larger values are only good close to the optimum.
  double initial_trust_region_radius = 1e6;
  /// Checked after every iteration: once it reads true the solver stops and the result is
  /// not usable (the problem stays unchanged). Lets a long global BA yield to a loop closure.
  const std::atomic<bool>* abort = nullptr;
  std::string Validate() const;
};

/// Defaults of ORB-SLAM's local BA (5 robust + 10 refine iterations, outliers rejected).
BundleAdjusterOptions LocalBaDefaults();
/// Defaults of ORB-SLAM's global BA (robust loss, no rejection, 2 threads, 15 iterations).
BundleAdjusterOptions GlobalBaDefaults();

/// Optimizes the non-fixed poses and points of *problem in place. summary.inlier has one
/// entry per problem->observations. usable is false if the problem is invalid (see
/// ValidateProblem) or Ceres fails; the problem is then left unchanged.
OptimizationSummary BundleAdjust(BundleProblem* problem, const BundleAdjusterOptions& options);

/// Local BA: a window of keyframes (not fixed) plus the periphery keyframes that also see
/// the window's points (fixed). Same as BundleAdjust with LocalBaDefaults() by default.
inline OptimizationSummary LocalBundleAdjustment(BundleProblem* problem,
                                                 const BundleAdjusterOptions& options = LocalBaDefaults()) {
  return BundleAdjust(problem, options);
}

/// Global BA over a whole map; fix at least the first keyframe (gauge).
inline OptimizationSummary GlobalBundleAdjustment(BundleProblem* problem,
                                                  const BundleAdjusterOptions& options = GlobalBaDefaults()) {
  return BundleAdjust(problem, options);
}

}  // namespace ccm::opt
