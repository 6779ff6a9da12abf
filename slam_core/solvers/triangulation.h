// Triangulation of one point from two or more calibrated views given as unit bearing
// vectors and camera poses. Every result says why it failed (low parallax, behind a
// camera, too large an error), so mapping code can count rejections by reason.
// Usage: TriangulateTwoView(f1, f2, cam2_from_cam1, options) -> point in cam1 frame;
//        TriangulateMultiView(observations, options) -> point in world frame.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/geometry/se3.h"

namespace ccm::solvers {

struct TriangulationOptions {
  /// Rays whose angle has a cosine above this are rejected (0.9998 ~ 1.15 deg, ORB-SLAM).
  /// For N views the largest pairwise parallax counts.
  double max_cos_parallax = 0.9998;
  /// Largest angular error allowed in any view, expressed in pixels at focal_px.
  double max_error_px = 2.45;  // sqrt(5.991) at sigma = 1 px, as ORB-SLAM
  /// Focal length in pixels converting max_error_px to an angle; must be set (> 0).
  double focal_px = 0.0;
  /// Minimum distance along each ray, in the units of the poses (0: only "in front").
  double min_depth = 0.0;

  std::string Validate() const;
};

enum class TriangulationStatus {
  kOk = 0,
  kInvalidInput,   // fewer than 2 views or bad options
  kLowParallax,    // rays (nearly) parallel
  kDegenerate,     // linear system has no finite solution
  kBehindCamera,   // point not in front of some camera (or closer than min_depth)
  kLargeError,     // angular error above max_error_px in some view
};

const char* TriangulationStatusName(TriangulationStatus status);

struct TriangulationResult {
  TriangulationStatus status = TriangulationStatus::kInvalidInput;
  /// Set only when status == kOk.
  std::optional<Eigen::Vector3d> point;
  /// Cosine of the largest ray angle (1 = parallel); valid unless kInvalidInput.
  double cos_parallax = 1.0;
  /// Largest error over the views, pixels at focal_px; valid once a point was computed.
  double max_error_px = 0.0;

  bool ok() const { return status == TriangulationStatus::kOk; }
};

/// One view of the point: its pose and the unit bearing of the observation.
struct BearingObservation {
  SE3 cam_from_world;
  Eigen::Vector3d bearing;  // unit, camera frame
};

/// Linear (DLT on bearings) triangulation in the world frame followed by the checks.
TriangulationResult TriangulateMultiView(const std::vector<BearingObservation>& views,
                                         const TriangulationOptions& options);

/// Two-view case: bearing1 in cam1, bearing2 in cam2; the point is in the cam1 frame.
TriangulationResult TriangulateTwoView(const Eigen::Vector3d& bearing1,
                                       const Eigen::Vector3d& bearing2,
                                       const SE3& cam2_from_cam1,
                                       const TriangulationOptions& options);

}  // namespace ccm::solvers
