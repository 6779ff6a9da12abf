// The frame being tracked: features, bearings, a keypoint grid and its current pose and
// map point matches. A value owned by the tracking thread; when it becomes a keyframe its
// features are shared (not copied) with the KeyFrame.
#pragma once

#include <memory>
#include <vector>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"
#include "slam_core/map/map_point.h"

namespace ccm {

struct VoFrame {
  int64_t stamp_ns = 0;
  int64_t index = 0;  ///< running frame number in the input sequence
  std::shared_ptr<const FrameFeatures> features;
  std::shared_ptr<const KeypointGrid> grid;
  std::vector<Eigen::Vector3d> bearings;  ///< unit, camera frame; zero if not unprojectable
  SE3 world_from_cam;
  std::vector<std::shared_ptr<MapPoint>> map_points;  ///< per keypoint; nullptr if unmatched
  std::vector<bool> outlier;                          ///< per keypoint, from pose optimization

  size_t size() const { return features ? features->size() : 0; }
  SE3 cam_from_world() const { return world_from_cam.inverse(); }
  int NumMatched() const;
  /// Drops matches flagged as outliers (and the flags).
  void DiscardOutliers();
};

/// Builds a frame from extracted features: bearings through the camera, keypoint grid.
VoFrame MakeVoFrame(int64_t stamp_ns, int64_t index, FrameFeatures features, const CameraModel& camera);

}  // namespace ccm
