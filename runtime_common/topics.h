// Topic names and default QoS profile names of the CCM-SLAM protocol (docs/architecture.md
// has the table). Profile names are defaults: runtimes can remap them from their config.
#pragma once

#include <string>

namespace ccm::rt {

// Agent -> server.
inline constexpr const char* kTopicKeyframes = "ccm/keyframes";              // KeyframeFull, new data
inline constexpr const char* kTopicMapPoints = "ccm/map_points";             // MapPointBatch, new data
inline constexpr const char* kTopicKeyframeUpdates = "ccm/keyframe_updates"; // KeyframeUpdate
inline constexpr const char* kTopicMapPointUpdates = "ccm/map_point_updates";// MapPointUpdateBatch
inline constexpr const char* kTopicAgentStatus = "ccm/agent_status";         // AgentStatus
// Server -> agents.
inline constexpr const char* kTopicServerToAgent = "ccm/server_to_agent";    // ServerToAgent
// Server -> operators (ccm_ctl status; idl/ccm_status.idl).
inline constexpr const char* kTopicServerStatus = "ccm/server_status";        // ServerStatus
// Server -> ROS 2 tools (ccm_server --ros2): ROS 2 topic /X travels as DDS topic "rt/X".
inline constexpr const char* kTopicRos2Tf = "rt/tf";                          // tf2_msgs/TFMessage
inline constexpr const char* kTopicRos2MapPoints = "rt/ccm/map_points";       // sensor_msgs/PointCloud2
inline std::string Ros2AgentPathTopic(int agent_id) { return "rt/ccm/agent_" + std::to_string(agent_id) + "/path"; }
inline std::string Ros2AgentPoseTopic(int agent_id) { return "rt/ccm/agent_" + std::to_string(agent_id) + "/pose"; }
/// The DDS partition of one agent: the agent writes all its data in it (so access control
/// can tell agents apart: docs/security.md) and the server writes that agent's
/// ServerToAgent messages in it, so they reach only that agent.
inline std::string AgentPartition(int agent_id) { return "agent_" + std::to_string(agent_id); }
/// The server's readers match every agent's partition (DDS partition wildcard).
inline constexpr const char* kAllAgentsPartition = "agent_*";

inline constexpr const char* kProfileParticipant = "ccm_participant";
inline constexpr const char* kProfileNewDataWriter = "ccm_new_data_writer";
inline constexpr const char* kProfileNewDataReader = "ccm_new_data_reader";
inline constexpr const char* kProfileUpdateWriter = "ccm_update_writer";
inline constexpr const char* kProfileUpdateReader = "ccm_update_reader";
inline constexpr const char* kProfileStatusWriter = "ccm_status_writer";
inline constexpr const char* kProfileStatusReader = "ccm_status_reader";
inline constexpr const char* kProfileServerWriter = "ccm_server_writer";
/// Server -> agent acks: their own writer so they never wait behind a neighbourhood.
inline constexpr const char* kProfileServerAckWriter = "ccm_server_ack_writer";
inline constexpr const char* kProfileServerReader = "ccm_server_reader";
inline constexpr const char* kProfileServerStatusWriter = "ccm_server_status_writer";
inline constexpr const char* kProfileServerStatusReader = "ccm_server_status_reader";
// ROS 2-visible outputs of ccm_server --ros2 (idl/ros2): ROS 2's QoS defaults (RELIABLE,
// VOLATILE, KEEP_LAST 10); the reader profile is what a ROS 2 subscriber uses by default.
inline constexpr const char* kProfileRos2Writer = "ccm_ros2_writer";
inline constexpr const char* kProfileRos2Reader = "ccm_ros2_reader";
// ccm_agent --ros2-image: a ROS 2 camera driver's Image / CameraInfo, read BEST_EFFORT (matches
// ROS 2's sensor-data and default writers) on a participant of its own.
inline constexpr const char* kProfileRos2Participant = "ccm_ros2_participant";
inline constexpr const char* kProfileRos2CameraReader = "ccm_ros2_camera_reader";
/// ROS 2 topic name ("/camera/image_raw" or "camera/image_raw": nodes here have no namespace)
/// -> its DDS topic ("rt/camera/image_raw").
inline std::string Ros2DdsTopic(const std::string& ros_name) {
  return "rt/" + (!ros_name.empty() && ros_name[0] == '/' ? ros_name.substr(1) : ros_name);
}

}  // namespace ccm::rt
