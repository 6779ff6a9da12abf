// Keyframes and map points the server sends to an agent (CCM-SLAM: the server's map
// around the agent, possibly from other agents), expressed relative to the agent's
// reference keyframe so they stay valid however the agent's frame drifted meanwhile.
// Value types produced by the runtime's conversion layer (from_msg) and applied by AgentVo.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"

namespace ccm {

struct ServerKeyframe {
  KeyframeId id;
  int64_t stamp_ns = 0;
  std::shared_ptr<const CameraModel> camera;  ///< the observing agent's camera
  std::shared_ptr<const FrameFeatures> features;
  SE3 ref_from_cam;  ///< pose in the frame of the agent's reference keyframe
  /// The agent holds this keyframe already (it said so): only id and pose travel, camera and
  /// features are null (downlink deltas, docs/protocol.md).
  bool held = false;
};

struct ServerMapPoint {
  MapPointId id;
  Eigen::Vector3d position_ref = Eigen::Vector3d::Zero();  ///< in the reference keyframe's frame
  // No descriptor: the agent takes it from the observing keyframes' keypoints.
  std::vector<std::pair<KeyframeId, int>> observations;  ///< (keyframe, keypoint index)
  /// The agent holds this point already: only id and position travel (no descriptor, no
  /// observations; downlink deltas, docs/protocol.md).
  bool held = false;
};

struct ServerMapData {
  KeyframeId reference_kf;  ///< the agent keyframe the data is expressed relative to
  std::vector<ServerKeyframe> keyframes;
  std::vector<ServerMapPoint> map_points;
  /// The server message's stamp (its clock; 0 in-process): the agent echoes the newest one
  /// it integrated with what it holds (AgentVo::Holdings).
  int64_t stamp_ns = 0;
};

/// The server keyframes an agent's local map holds, as of the newest server data integrated.
struct ServerHoldings {
  int64_t applied_stamp_ns = 0;
  std::vector<KeyframeId> keyframes;
};

/// What applying one ServerMapData did (cumulative in AgentVoStats).
struct ServerDataStats {
  int64_t messages_applied = 0;
  int64_t messages_stale = 0;  ///< reference keyframe no longer in the local map: dropped
  int64_t keyframes_added = 0;
  int64_t keyframes_updated = 0;
  int64_t keyframes_not_held = 0;  ///< a pose for a keyframe the local map no longer has
  int64_t points_added = 0;
  int64_t points_updated = 0;
  int64_t points_not_held = 0;  ///< a position for a point the local map no longer has
  int64_t observations_added = 0;
};

}  // namespace ccm
