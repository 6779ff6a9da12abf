// What the server sends back to an agent (CCM-SLAM 4.5): the k keyframes most covisible
// with the agent's reference keyframe, from any other agent (its own recent ones it has;
// its own old ones too with own_keyframes_after_s, which its bounded local map forgot), and their
// points, expressed relative to that reference keyframe in the agent's VO scale (the
// handler's lambda), so the agent can place them however its own frame drifted. Synchronous; takes the map's structure lock
// shared while it copies.
#pragma once

#include <optional>
#include <unordered_set>

#include "slam_core/exchange/server_map_data.h"
#include "slam_core/server/map_stack.h"

namespace ccm {

struct NeighbourhoodOptions {
  int keyframes = 5;        ///< k
  size_t max_points = 4096;  ///< cap per message (IDL bound)
  /// > 0: also the agent's own keyframes this much older than its reference keyframe [s].
  double own_keyframes_after_s = 0.0;
  /// With own_keyframes_after_s: when the covisible ones leave room, also the agent's own old
  /// keyframes whose camera centre lies within this share of the reference keyframe's scene
  /// depth of it and that look the same way (within kNearbyMaxAngleDeg), nearest first. An agent
  /// back at a place it flew before any loop joined the two passes has no covisibility with
  /// its first pass yet; its trajectory drifted little over one pass, so nearness finds it.
  /// 0: covisible ones only.
  double own_nearby_depth_ratio = 0.5;
};

/// Own old keyframes sent for nearness only look at most this far away from the reference.
inline constexpr double kNearbyMaxAngleDeg = 30.0;

/// nullopt if the server does not know `reference_kf` (not arrived yet) or has nothing to send.
/// `held`: keyframes the agent holds already (it said so); they go as poses only.
std::optional<ServerMapData> AgentNeighbourhood(const MapStack& stack, AgentId agent, KeyframeId reference_kf,
                                                const NeighbourhoodOptions& options,
                                                const std::unordered_set<KeyframeId>* held = nullptr);

}  // namespace ccm
