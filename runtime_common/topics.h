// Topic names and default QoS profile names of the CCM-SLAM protocol (docs/architecture.md
// has the table). Profile names are defaults: runtimes can remap them from their config.
#pragma once

namespace ccm::rt {

// Agent -> server.
inline constexpr const char* kTopicKeyframes = "ccm/keyframes";              // KeyframeFull, new data
inline constexpr const char* kTopicMapPoints = "ccm/map_points";             // MapPointFull, new data
inline constexpr const char* kTopicKeyframeUpdates = "ccm/keyframe_updates"; // KeyframeUpdate
inline constexpr const char* kTopicMapPointUpdates = "ccm/map_point_updates";// MapPointUpdate
inline constexpr const char* kTopicAgentStatus = "ccm/agent_status";         // AgentStatus
// Server -> agents.
inline constexpr const char* kTopicServerToAgent = "ccm/server_to_agent";    // ServerToAgent

inline constexpr const char* kProfileParticipant = "ccm_participant";
inline constexpr const char* kProfileNewDataWriter = "ccm_new_data_writer";
inline constexpr const char* kProfileNewDataReader = "ccm_new_data_reader";
inline constexpr const char* kProfileUpdateWriter = "ccm_update_writer";
inline constexpr const char* kProfileUpdateReader = "ccm_update_reader";
inline constexpr const char* kProfileStatusWriter = "ccm_status_writer";
inline constexpr const char* kProfileStatusReader = "ccm_status_reader";
inline constexpr const char* kProfileServerWriter = "ccm_server_writer";
inline constexpr const char* kProfileServerReader = "ccm_server_reader";

}  // namespace ccm::rt
