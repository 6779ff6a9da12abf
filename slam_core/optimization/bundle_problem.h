// Plain value-type descriptions of bundle-adjustment problems. The optimizers never see
// the map: the caller (map/server facade) copies the keyframes, points and observations it
// wants optimized into a BundleProblem, runs an optimizer (which updates the problem in
// place and returns a summary) and writes the results and outlier flags back.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"

namespace ccm::opt {

/// One keyframe (or frame) pose. `fixed` poses keep their value but still constrain the
/// points they observe (periphery keyframes of a local BA, the gauge pose of a global BA).
struct PoseBlock {
  std::uint64_t id = 0;  ///< caller's id (e.g. KeyframeId value); not used by the solver
  SE3 world_from_cam;
  bool fixed = false;
  int camera_index = 0;  ///< index into BundleProblem::cameras
};

/// One 3D point in world coordinates.
struct PointBlock {
  std::uint64_t id = 0;
  Eigen::Vector3d position_w = Eigen::Vector3d::Zero();
  bool fixed = false;
  /// >= 0: optimized as an inverse depth along its ray from this pose (the ray held), for
  /// points of low parallax whose depth is nearly free; -1: as a free 3D position.
  int anchor_pose = -1;
};

/// A keypoint measurement of point `point_index` in pose `pose_index`, in distorted pixels
/// as detected. sigma_px is the keypoint's standard deviation: ORB-SLAM uses
/// scale_factor^octave (1.2^level) px, see SigmaForPyramidLevel().
struct Observation {
  int pose_index = 0;
  int point_index = 0;
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double sigma_px = 1.0;
};

/// Everything a bundle adjustment needs. Cameras are shared, immutable and may differ per
/// pose (collaborative SLAM: each agent has its own calibration).
struct BundleProblem {
  std::vector<std::shared_ptr<const CameraModel>> cameras;
  std::vector<PoseBlock> poses;
  std::vector<PointBlock> points;
  std::vector<Observation> observations;
};

/// Outcome of one optimizer call. Costs are Ceres costs: 0.5 * sum of robustified squared
/// whitened residuals (pixels / sigma_px), over the observations active in the first
/// (initial_cost) and last (final_cost) round; they are comparable only within one round.
struct OptimizationSummary {
  bool usable = false;  ///< the solver ran and produced a finite solution
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;  ///< total solver iterations over all rounds
  /// Of those, steps Ceres tried and threw away (the cost went up, or a point stopped projecting
  /// and the evaluation failed): each costs a linear solve like a good one.
  int rejected_steps = 0;
  double solve_time_s = 0.0;
  /// Per observation (same order as BundleProblem::observations, or the pose-only input):
  /// false for outliers (chi2 above threshold after the final round) and for observations
  /// that could not be projected (point behind the camera / outside the camera model).
  std::vector<bool> inlier;
  int num_inliers = 0;
  std::string message;  ///< Ceres' one-line report of the last round, for logs
};

/// ORB-SLAM's keypoint sigma for pyramid level `level` and scale factor `scale` (1.2).
double SigmaForPyramidLevel(int level, double scale_factor = 1.2);

/// 95% chi-square quantiles used as outlier thresholds on squared whitened errors.
inline constexpr double kChi2Mono2Dof = 5.991;

/// Whitened squared reprojection error (chi2) of one observation; negative if the point
/// cannot be projected (behind the camera or outside the model's domain).
double ObservationChi2(const BundleProblem& problem, const Observation& obs);

/// Root-mean-square reprojection error in pixels (not whitened) over the observations
/// whose mask entry is true (all if mask is null); unprojectable ones are skipped.
double ReprojectionRmsePx(const BundleProblem& problem, const std::vector<bool>* mask = nullptr);

/// Empty if indices and cameras are consistent, otherwise what is wrong.
std::string ValidateProblem(const BundleProblem& problem);

}  // namespace ccm::opt
