// Deterministic synthetic protocol messages for the link demo, transport tests and
// benchmarks: message
// i of a stream is a pure function of (agent, i, features), so a receiver can regenerate
// what the sender sent and compare field by field.
#pragma once

#include <cstdint>
#include <vector>

#include "idl/ccm_msgs.h"

namespace ccm::synthetic {

msg::KeyframeFull MakeKeyframe(std::uint16_t agent, std::uint64_t index, int num_features,
                               int num_associations);
msg::MapPointFull MakeMapPoint(std::uint16_t agent, std::uint64_t index, int num_observations);
msg::KeyframeUpdate MakeKeyframeUpdate(std::uint16_t agent, std::uint64_t index);
msg::MapPointUpdate MakeMapPointUpdate(std::uint16_t agent, std::uint64_t index);
msg::AgentStatus MakeAgentStatus(std::uint16_t agent, std::uint64_t index);
msg::ServerToAgent MakeServerToAgent(std::uint16_t agent, int num_keyframes, int features_per_kf,
                                     int num_map_points, int num_acks);

/// Stream index encoded in a keyframe id (agent id + counter, counter = index + 1).
std::uint64_t KeyframeCounter(const msg::KeyframeFull& kf);

}  // namespace ccm::synthetic
