// ccm_server --ros2 (issue 32): the team's map for ROS 2 tools on the same DDS domain, with no
// bridge and no ROS on the ground station. ROS 2 speaks DDS with its own conventions, and we
// follow them: ROS topic /X is DDS topic "rt/X", types are named <pkg>::msg::dds_::<Type>_
// (idl/ros2/ros2_msgs.idl), QoS is ROS 2's default (qos_profiles: ccm_ros2_writer).
//
// Published, every period_s (and the cloud every cloud_period_s), from a snapshot of the back-end:
//   /ccm/agent_<id>/path  nav_msgs/Path         the agent's keyframes in its server map
//   /ccm/agent_<id>/pose  geometry_msgs/PoseStamped  its newest keyframe
//   /tf                   tf2_msgs/TFMessage    map frame -> "agent_<id>" (that keyframe)
//   /ccm/map_points       sensor_msgs/PointCloud2  the largest map's points, decimated, x y z float32
// Frames: the largest server map (the team's, once fused) is "map"; a map not fused yet is
// "ccm_map_<n>" (its number in the stack), so agents that do not share a map are never drawn as if
// they did. Stamps are the keyframes' (camera) stamps; the cloud's is the newest keyframe's.
// Poses are camera poses in the map (camera frame: x right, y down, z forward, as the agent's
// camera; ROS' body convention would need the camera's mounting, which the server does not know).
// The daemon publishes on a participant of its own (CreateWithOwnParticipant: profile
// ccm_ros2_participant, the ROS 2 side's domain, no DDS-Security), so a secure ground station
// can still show its map to ROS 2 tools on an open domain without opening the team's.
// Called from one thread (the daemon's main loop); it owns no thread.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "idl/ros2/ros2_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/typed_endpoints.h"
#include "slam_core/server/map_stack_snapshot.h"
#include "slam_core/server/server_backend.h"

namespace ccm::server {

struct Ros2OutputOptions {
  double period_s = 1.0;         ///< paths, poses and tf
  double cloud_period_s = 5.0;   ///< the point cloud (it is the big one)
  size_t max_cloud_points = 50000;
  int domain_id = -1;            ///< the ROS 2 side's domain (CreateWithOwnParticipant); -1: the team's
  std::string Validate() const;
};

/// What one publishing round puts on the wire (built without DDS, so tests check it directly).
struct Ros2Frame {
  struct Agent {
    AgentId id = 0;
    nav_msgs::msg::dds_::Path_ path;
    geometry_msgs::msg::dds_::PoseStamped_ pose;
  };
  std::vector<Agent> agents;
  tf2_msgs::msg::dds_::TFMessage_ tf;
  sensor_msgs::msg::dds_::PointCloud2_ cloud;  ///< width 0 when the stack has no point
};

/// The frame name of a server map: "map" for the largest one, else "ccm_map_<n>".
std::string Ros2FrameId(MapId map, MapId largest);
/// Builds one round's messages from a snapshot (`with_cloud`: also the decimated cloud).
Ros2Frame BuildRos2Frame(const MapStackSnapshot& stack, bool with_cloud, size_t max_cloud_points);

class Ros2Outputs {
 public:
  /// On `session` (which must outlive the outputs).
  static std::unique_ptr<Ros2Outputs> Create(rt::DdsSession& session, const Ros2OutputOptions& options,
                                             std::string* error);
  /// On a participant of their own: `team`'s QoS file, options.domain_id (else team's domain),
  /// profile ccm_ros2_participant, no DDS-Security whatever `team` uses.
  static std::unique_ptr<Ros2Outputs> CreateWithOwnParticipant(const rt::SessionOptions& team,
                                                               const Ros2OutputOptions& options, std::string* error);
  int domain_id() const { return session_.options().domain_id; }
  /// Publishes what is due at `now_s` (any monotonic seconds; the back-end's snapshot is taken
  /// only then). False and *error if a writer could not be created.
  bool PublishDue(const ServerBackend& backend, double now_s, std::string* error);
  int64_t rounds() const { return rounds_; }

 private:
  Ros2Outputs(rt::DdsSession& session, const Ros2OutputOptions& options) : session_(session), options_(options) {}
  struct AgentWriters {
    std::unique_ptr<rt::TypedWriter<nav_msgs::msg::dds_::Path_PubSubType>> path;
    std::unique_ptr<rt::TypedWriter<geometry_msgs::msg::dds_::PoseStamped_PubSubType>> pose;
  };
  std::unique_ptr<rt::DdsSession> own_session_;  // CreateWithOwnParticipant; declared first: destroyed last
  rt::DdsSession& session_;
  const Ros2OutputOptions options_;
  std::unique_ptr<rt::TypedWriter<tf2_msgs::msg::dds_::TFMessage_PubSubType>> tf_;
  std::unique_ptr<rt::TypedWriter<sensor_msgs::msg::dds_::PointCloud2_PubSubType>> cloud_;
  std::map<AgentId, AgentWriters> agents_;
  double next_s_ = -1.0, next_cloud_s_ = -1.0;
  int64_t rounds_ = 0;
};

}  // namespace ccm::server
