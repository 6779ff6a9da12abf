// Read-only views of the server's map stack for everything outside the back-end (map view,
// run outputs, the replay's drawing, persistence), and what a back-end starts from when it
// does not start empty.
//
// A MapStackSnapshot is taken in one call (ServerBackend::Snapshot()): the live maps as
// const pointers, then the handlers and the map id counter, then the events. The maps are
// shared with the running back-end, not copied: their contents keep changing, so read them
// through the Map's thread-safe readers or under the map's shared structure lock
// (structure_mutex() is usable on a const map), never both a map's lock and a back-end call.
// A handler taken after the maps may point to a map created (or fused away) meanwhile;
// readers skip such handlers.
#pragma once

#include <cstdint>
#include <memory>
#include <set>
#include <vector>

#include "slam_core/server/map_stack.h"
#include "slam_core/server/server_event.h"

namespace ccm {

struct ServerKeyframePose {
  KeyframeId id;
  MapId map;           ///< server map it is in
  MapId segment;       ///< the agent's VO segment
  int64_t stamp_ns = 0;
  SE3 world_from_cam;  ///< in that server map
  bool in_map = true;  ///< false: anchored (skipped or removed), pose through its anchor
};

/// Two keyframes of one agent in one map, far apart in time, that share map points: a place
/// the agent flew again and the map holds once (a loop joined them, or the agent tracked its
/// earlier points there, its own or the server's). Diagnostics for the fusion benchmark.
struct RevisitLink {
  KeyframeId early, late;
  int64_t early_ns = 0, late_ns = 0;
  int shared_points = 0;
};

struct MapSummary {
  MapId id;
  size_t keyframes = 0, map_points = 0, anchored = 0;
  std::set<AgentId> agents;
};

struct MapStackSnapshot {
  std::vector<std::shared_ptr<const ServerMap>> maps;  ///< live maps, by id
  std::vector<AgentHandler> handlers;
  uint64_t next_map_counter = 0;
  std::vector<ServerEvent> events;  ///< every event so far, in order

  /// Maps, then counter and handlers, of a stack (no events: the back-end adds its own).
  static MapStackSnapshot Of(const MapStack& stack);
  /// nullptr if the snapshot has no map `id`.
  std::shared_ptr<const ServerMap> Map(MapId id) const;
  /// The map that holds (or anchors) keyframe `kf`; nullptr if none.
  std::shared_ptr<const ServerMap> MapHolding(KeyframeId kf) const;
  /// Size and agents of every map (each map's counts read now, not at the snapshot).
  std::vector<MapSummary> Summaries() const;
  /// Every keyframe of `agent` in the maps (anchored ones too), sorted by stamp; takes each
  /// map's structure lock shared in turn.
  std::vector<ServerKeyframePose> AgentTrajectory(AgentId agent) const;
  /// Every pair of `agent`'s keyframes in one map whose covisibility weight is at least
  /// `min_shared` and whose stamps are at least `min_gap_ns` apart.
  std::vector<RevisitLink> AgentRevisitLinks(AgentId agent, int64_t min_gap_ns, int min_shared) const;
};

/// What a back-end starts from instead of an empty stack: a loaded file (map_persistence.h),
/// or a test's hand-built maps. Whoever keeps a pointer to `stack` must not edit it while
/// the back-end runs stages.
struct RestoredStack {
  std::shared_ptr<MapStack> stack;
  std::vector<ServerEvent> events;
};

}  // namespace ccm
