// The server's map stack (CCM-SLAM 4.3-4.4): the server maps and, per agent handler
// (agent, VO map segment), which map it registers into, the Sim(3) from the segment's VO
// frame to that map and the scale factor lambda between VO and map (Forster et al.).
// A new segment starts its own map; a fusion re-points every handler of the absorbed map
// with its Sim(3) composed. Thread-safe: one internal mutex, a leaf (no map lock is taken
// while it is held); handler records are returned by value.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "slam_core/geometry/sim3.h"
#include "slam_core/server/server_map.h"

namespace ccm {

/// Server id space: server maps are MapId::Make(kServerAgent, n).
inline constexpr AgentId kServerAgent = 0;

struct AgentHandler {
  AgentId agent = 0;
  MapId segment;
  MapId map;                 ///< server map the segment registers into
  Sim3 map_from_segment;     ///< VO frame of the segment -> server map
  double scale = 1.0;        ///< lambda: map metres per VO metre near the agent
  KeyframeId last_keyframe;  ///< newest registered keyframe of the segment
  int64_t keyframes = 0;     ///< keyframes registered
};

class MapStack {
 public:
  explicit MapStack(MapOptions map_options) : map_options_(map_options) {}

  /// The map of (agent, segment); a new handler gets a new map. *created tells which.
  std::shared_ptr<ServerMap> MapFor(AgentId agent, MapId segment, bool* created = nullptr);
  std::optional<AgentHandler> Handler(AgentId agent, MapId segment) const;
  /// Applies `edit` to the handler under the stack's lock (keep it short, no map calls).
  void EditHandler(AgentId agent, MapId segment, const std::function<void(AgentHandler*)>& edit);
  std::vector<AgentHandler> Handlers() const;
  std::vector<AgentHandler> HandlersOfMap(MapId map) const;
  /// Handlers of `agent`, any segment.
  std::vector<AgentHandler> HandlersOfAgent(AgentId agent) const;

  std::shared_ptr<ServerMap> GetMap(MapId id) const;
  std::vector<std::shared_ptr<ServerMap>> Maps() const;  ///< live maps, by id
  size_t num_maps() const;
  /// The live map that holds (or anchors) keyframe `kf`; nullptr if none.
  std::shared_ptr<ServerMap> MapHolding(KeyframeId kf) const;

  /// After fusing `from` into `into` (p_into = into_from_from * p_from): handlers of `from`
  /// move with their Sim(3) and scale composed; `from` leaves the stack.
  void Repoint(MapId from, MapId into, const Sim3& into_from_from);

  /// Persistence: restore a map / handler / the id counter as saved.
  void RestoreMap(std::shared_ptr<ServerMap> map);
  void RestoreHandler(const AgentHandler& handler);
  uint64_t next_map_counter() const;
  void set_next_map_counter(uint64_t n);
  const MapOptions& map_options() const { return map_options_; }

 private:
  const MapOptions map_options_;
  mutable std::mutex mutex_;
  std::map<MapId, std::shared_ptr<ServerMap>> maps_;
  std::map<std::pair<AgentId, MapId>, AgentHandler> handlers_;
  uint64_t next_map_ = 1;
};

}  // namespace ccm
