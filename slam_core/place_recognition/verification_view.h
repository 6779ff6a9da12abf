// One keyframe as place verification sees it: a value snapshot (features, camera, pyramid,
// per-keypoint 3D points in its own camera frame, direct index), so that keyframes of agent
// maps, server maps and different cameras can be compared. Built by the caller, e.g. with
// MakeVerificationView (map_adapter.h).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/camera.h"
#include "slam_core/place_recognition/bow_vector.h"

namespace ccm {

/// One keyframe as seen by verification.
struct VerificationView {
  std::shared_ptr<const CameraModel> camera;
  FrameFeatures features;            ///< keypoints (distorted pixels) + descriptors
  ScalePyramid pyramid = ScalePyramid::Make(8, 1.2);
  /// Per keypoint: its map point in THIS keyframe's camera frame, or NaN if it has none.
  /// Each view may be in its own map's scale.
  std::vector<Eigen::Vector3d> points_cam;
  /// Direct index of the keypoints (Vocabulary::Transform with the same levels_up for both).
  FeatureVector feature_vector;

  bool HasPoint(int i) const { return points_cam[i].allFinite(); }
  /// Empty if consistent, else the problem (sizes, missing camera).
  std::string Validate() const;
};

}  // namespace ccm
