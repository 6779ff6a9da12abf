// Homography between two views of a plane, from bearing correspondences: normalized
// 4-point DLT inside a seeded RANSAC, re-estimated on all inliers, plus decomposition
// into the (up to four) motions R, t, n. Used by two-view initialization when the
// scene is planar or the baseline is too small for an essential matrix.
// Bearings must point forward (z > 0): H maps normalized image planes x2 ~ H x1.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "slam_core/geometry/se3.h"
#include "slam_core/solvers/solver_common.h"

namespace ccm::solvers {

struct HomographyOptions {
  /// threshold_px bounds the transfer error in each direction (1->2 and 2->1).
  RansacOptions ransac;
  int min_inliers = 15;

  std::string Validate() const;
};

struct HomographyResult {
  SolverStatus status = SolverStatus::kInvalidInput;
  std::string message;
  /// x2 ~ H x1 on normalized planes (x = bearing / bearing.z), scaled to |H|_F = 1.
  Eigen::Matrix3d cam2_H_cam1 = Eigen::Matrix3d::Identity();
  std::vector<bool> inliers;
  int num_inliers = 0;
  int iterations = 0;

  bool ok() const { return status == SolverStatus::kOk; }
};

HomographyResult EstimateHomography(const std::vector<Eigen::Vector3d>& bearings1,
                                    const std::vector<Eigen::Vector3d>& bearings2,
                                    const HomographyOptions& options);

/// One motion hypothesis of a homography: X2 = R X1 + t for points on the plane
/// n . X1 = 1 (so |t| is relative to the plane distance from cam1).
struct HomographyMotion {
  SE3 cam2_from_cam1;
  Eigen::Vector3d plane_normal_cam1;
};

/// Up to four candidate motions (OpenCV's analytic decomposition, Malis & Vargas);
/// cheirality has to pick among them (see two_view_init.h).
std::vector<HomographyMotion> DecomposeHomography(const Eigen::Matrix3d& cam2_H_cam1);

/// Transfer error of x2 vs H x1 on the normalized plane (unitless; times focal = px).
/// Returns a huge value when a point maps to infinity.
double HomographyTransferError(const Eigen::Matrix3d& H, const Eigen::Vector2d& x1,
                               const Eigen::Vector2d& x2);

}  // namespace ccm::solvers
