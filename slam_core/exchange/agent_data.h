// What an agent sends to the server, as middleware-free value types: full keyframes and
// map points (new data, sent once), pose/position updates (sent whenever the agent's local
// BA moves them) and the batch that carries them together with the agent's reference
// keyframe. The agent's ChangePacker (vo/) produces them from the VO's map; the server
// back-end (server/) consumes them; the runtimes' conversion layer maps them to and from
// the IDL types. Poses are relative (CCM-SLAM 4.5): a keyframe relative to its predecessor
// and to its covisibility parent, a map point relative to its reference keyframe, all in
// the agent's VO scale, so data that waits in a queue lands correctly after the server moved
// the map.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"

namespace ccm {

/// A keyframe as the agent sends it once, in full.
struct KeyframeData {
  KeyframeId id;
  MapId segment;  ///< the agent's VO map segment (a new one after tracking was lost for good)
  int64_t stamp_ns = 0;
  std::shared_ptr<const CameraModel> camera;
  int pyramid_levels = 8;
  double pyramid_scale_factor = 1.2;
  std::shared_ptr<const FrameFeatures> features;
  /// (keypoint index, map point) for every keypoint that observes a map point. Points of
  /// other agents appear here when the agent tracked data the server shared with it.
  std::vector<std::pair<int, MapPointId>> point_links;
  KeyframeId predecessor;  ///< the agent's previous keyframe in this segment (Invalid: first)
  SE3 pred_from_cam;       ///< this keyframe's camera in the predecessor's camera frame
  /// Spanning-tree parent (strongest covisibility neighbour) at packing time, possibly a
  /// keyframe of another agent that the server shared (Invalid: none).
  KeyframeId parent;
  SE3 parent_from_cam;
  /// Pose in the segment's VO frame. Only a fallback: the server places a keyframe with
  /// this only if neither predecessor nor parent is known (e.g. both were lost).
  SE3 segment_from_cam;
  /// A near-duplicate of `parent`, a keyframe the server has in full (NearDuplicateOf on the
  /// agent): only its poses travel, no features and no point links (empty), and the server
  /// keeps it as a pose anchor on `parent` (its trajectory), never in the map. It would
  /// have dropped the features of such a keyframe anyway (Forster et al.).
  bool anchor_only = false;
  /// Not on the wire: set by the server's reassembly when the keyframe left before every
  /// point of its own agent it links had arrived (after an outage the reliable streams come
  /// back one after the other, keyframes seconds before their points). Its links are then a
  /// minority of its evidence, often points of an earlier pass only.
  bool points_incomplete = false;
};

/// A map point as the agent sends it once, in full.
struct MapPointData {
  MapPointId id;
  MapId segment;
  KeyframeId reference_kf;  ///< a keyframe observing it; the position is in its camera frame
  Eigen::Vector3d position_ref = Eigen::Vector3d::Zero();  ///< VO scale [m]
  OrbDescriptor descriptor{};  ///< not on the wire (protocol v4): the server derives it from the observations
  /// (own keyframe, keypoint index): those no keyframe's point links carry (the agent's
  /// ChangePacker leaves out observations by keyframes whose links name the point; the
  /// server attaches such links when the point arrives). May be empty.
  std::vector<std::pair<KeyframeId, int>> observations;
};

/// New relative pose of a keyframe the server already has (agent's local BA moved it).
struct KeyframePoseUpdate {
  KeyframeId id;
  MapId segment;
  KeyframeId predecessor;
  SE3 pred_from_cam;
  KeyframeId parent;
  SE3 parent_from_cam;
};

/// New position of a map point the server already has, relative to its reference keyframe.
struct MapPointPositionUpdate {
  MapPointId id;
  KeyframeId reference_kf;
  Eigen::Vector3d position_ref = Eigen::Vector3d::Zero();
};

/// One message's worth of agent data. Everything in it belongs to `agent`.
struct AgentBatch {
  AgentId agent = 0;
  MapId segment;            ///< the agent's current segment
  KeyframeId reference_kf;  ///< the newest keyframe sent (the VO reference once sent): the server replies relative to it
  int64_t stamp_ns = 0;     ///< agent clock when packed
  std::vector<KeyframeData> keyframes;
  std::vector<MapPointData> map_points;
  std::vector<KeyframePoseUpdate> keyframe_updates;
  std::vector<MapPointPositionUpdate> map_point_updates;

  bool empty() const {
    return keyframes.empty() && map_points.empty() && keyframe_updates.empty() && map_point_updates.empty();
  }
};

/// What a batch holds in memory, approximately (keypoints, descriptors, links, points,
/// updates): what a receiver's queue bound counts.
size_t ApproxBatchBytes(const AgentBatch& batch);

/// Limits a receiver enforces before data reaches the map (hostile or corrupted input).
struct AgentDataLimits {
  size_t max_keypoints = 4000;
  size_t max_observations = 64;
  double max_abs_coordinate_m = 1e6;  ///< translations and positions beyond this are rejected
};

/// Empty if `kf` is well formed for `agent`, else what is wrong ("keypoint 12: octave 9 out
/// of range", "point link 3: keypoint index 5000 out of range", ...).
std::string ValidateKeyframeData(const KeyframeData& kf, AgentId agent, const AgentDataLimits& limits = {});
std::string ValidateMapPointData(const MapPointData& mp, AgentId agent, const AgentDataLimits& limits = {});
std::string ValidateKeyframePoseUpdate(const KeyframePoseUpdate& u, AgentId agent, const AgentDataLimits& limits = {});
std::string ValidateMapPointPositionUpdate(const MapPointPositionUpdate& u, AgentId agent,
                                           const AgentDataLimits& limits = {});

}  // namespace ccm
