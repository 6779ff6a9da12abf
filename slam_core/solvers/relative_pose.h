// Two-view relative pose (essential matrix) from bearing correspondences: 5-point
// (Stewenius or Nister) or 8-point minimal solvers inside OpenGV's RANSAC (hypotheses
// scored by Sampson angle; OpenGV picks among the four decompositions by cheirality of the
// sample), robust nonlinear refinement, final inliers also pass OpenGV's triangulating
// residual, so every inlier lies in front of both cameras.
// Translation is known only up to scale and is returned with unit norm; with (near) zero
// baseline it is meaningless: InitializeTwoView checks parallax, this function does not.
// Usage: options.ransac.focal_px = fx; auto r = EstimateRelativePose(b1, b2, options);
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "slam_core/geometry/se3.h"
#include "slam_core/solvers/solver_common.h"

namespace ccm::solvers {

enum class RelativePoseAlgorithm { kStewenius5pt, kNister5pt, kEightPoint };

struct RelativePoseOptions {
  RelativePoseAlgorithm algorithm = RelativePoseAlgorithm::kStewenius5pt;
  /// threshold_px bounds the angular reprojection error in each of the two views.
  RansacOptions ransac;
  /// Levenberg-Marquardt refinement of R, t on the RANSAC inliers (Sampson angular
  /// error, Cauchy loss at half the threshold), then inliers re-selected.
  bool refine = true;
  /// Fewer inliers than this is a failure.
  int min_inliers = 15;

  std::string Validate() const;
};

struct RelativePoseResult {
  SolverStatus status = SolverStatus::kInvalidInput;
  std::string message;
  /// Maps points from cam1 into cam2; |translation| = 1.
  SE3 cam2_from_cam1;
  /// inliers[i]: correspondence i fits the model and triangulates in front of both views.
  std::vector<bool> inliers;
  int num_inliers = 0;
  int iterations = 0;

  bool ok() const { return status == SolverStatus::kOk; }
};

/// bearings1[i] (cam1) and bearings2[i] (cam2) are unit vectors of the same point.
RelativePoseResult EstimateRelativePose(const std::vector<Eigen::Vector3d>& bearings1,
                                        const std::vector<Eigen::Vector3d>& bearings2,
                                        const RelativePoseOptions& options);

/// Robust refinement used by EstimateRelativePose, exposed for other motion sources
/// (homography decomposition): Levenberg-Marquardt on SO(3) x S^2 over the Sampson
/// angular errors of `indices`, Cauchy loss with scale loss_scale_rad. |t| = 1 on return.
SE3 RefineRelativePose(const SE3& cam2_from_cam1, const std::vector<Eigen::Vector3d>& bearings1,
                       const std::vector<Eigen::Vector3d>& bearings2, const std::vector<int>& indices,
                       double loss_scale_rad);

/// How far the best motion whose translation direction lies at least min_angle_deg from the
/// chosen one falls behind it, in robust cost (Cauchy at 2 sigma, units of sigma^2, summed
/// over `indices`). A short forward move in a partly planar view has a second minimum with
/// a sideways translation (73-99 deg away) that costs about the same: the view cannot tell
/// the two apart, whatever the camera.
struct MotionAmbiguity {
  double chosen_cost = 0.0;
  double rival_cost = std::numeric_limits<double>::infinity();
  SE3 rival;
  double rival_angle_deg = 0.0;
  double gap() const { return rival_cost - chosen_cost; }
};
MotionAmbiguity ProfileTranslationDirections(const SE3& cam2_from_cam1,
                                            const std::vector<Eigen::Vector3d>& bearings1,
                                            const std::vector<Eigen::Vector3d>& bearings2,
                                            const std::vector<int>& indices, double sigma_rad,
                                            double min_angle_deg);

/// Essential matrix of a motion: x2^T E x1 = 0 for bearings x1 (cam1), x2 (cam2).
Eigen::Matrix3d EssentialFromPose(const SE3& cam2_from_cam1);

}  // namespace ccm::solvers
