// Absolute camera pose from 2D-3D correspondences (bearings + world points): P3P (Kneip
// by default) inside OpenGV's RANSAC, then nonlinear refinement of the angular error on
// the inliers. Used for relocalization and tracking against a map without a motion prior.
// Usage: options.ransac.focal_px = fx; auto r = EstimateAbsolutePose(bearings, points, options);
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "slam_core/geometry/se3.h"
#include "slam_core/solvers/solver_common.h"

namespace ccm::solvers {

// EPnP is not offered: OpenGV 1.0's sample-consensus EPNP case falls through into GP3P.
enum class AbsolutePoseAlgorithm { kKneipP3P, kGaoP3P };

struct AbsolutePoseOptions {
  AbsolutePoseAlgorithm algorithm = AbsolutePoseAlgorithm::kKneipP3P;
  /// threshold_px bounds the angular reprojection error.
  RansacOptions ransac;
  /// Nonlinear refinement on the inliers (OpenGV optimize_nonlinear).
  bool refine = true;
  int min_inliers = 10;

  std::string Validate() const;
};

struct AbsolutePoseResult {
  SolverStatus status = SolverStatus::kInvalidInput;
  std::string message;
  SE3 world_from_cam;
  /// inliers[i]: correspondence i reprojects within the threshold and lies in front.
  std::vector<bool> inliers;
  int num_inliers = 0;
  int iterations = 0;

  bool ok() const { return status == SolverStatus::kOk; }
  SE3 cam_from_world() const { return world_from_cam.inverse(); }
};

/// bearings[i]: unit bearing (camera frame) of points_world[i].
AbsolutePoseResult EstimateAbsolutePose(const std::vector<Eigen::Vector3d>& bearings,
                                        const std::vector<Eigen::Vector3d>& points_world,
                                        const AbsolutePoseOptions& options);

}  // namespace ccm::solvers
