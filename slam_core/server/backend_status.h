// The back-end's counters and work in progress, as one value (ServerBackend::Status()): the
// statistics sink's totals, the depth of every stage's queue, the agents and whether any
// stage has work. A copy: reading it takes no lock.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/server/place_matcher.h"

namespace ccm {

struct AgentCounters {
  int64_t batches = 0;
  int64_t keyframes_registered = 0;
  int64_t keyframes_duplicate = 0;   ///< skipped as near-duplicates (anchored)
  int64_t keyframes_anchor_only = 0; ///< near-duplicates the agent sent as anchors only
  /// Keyframes whose links mostly disagreed, placed on the points their predecessor sees
  /// (an agent back at old points before the loop was closed); registration.cc RefinePose.
  int64_t keyframes_kept_on_track = 0;
  /// Registered before their own points arrived (after an outage): mapped and queried for
  /// place recognition once the points came (registration.h, RegisteredKeyframe::deferred).
  int64_t keyframes_deferred = 0;
  /// Refinements against the map that pulled a keyframe further than its agent's VO drifts
  /// in a step, with neither its track nor a clear majority of its links for it: refused.
  int64_t refinements_refused = 0;
  int64_t points_registered = 0;
  int64_t updates_applied = 0;
  int64_t updates_ignored = 0;
  int64_t rejected = 0;              ///< items that failed validation
  int64_t batches_dropped = 0;       ///< queue full (max_queued_batches_per_agent / _bytes_per_agent)
  int64_t segments_refused = 0;      ///< batches of a segment beyond max_segments_per_agent
  std::string last_rejection;
  std::vector<double> keyframe_ms;   ///< registration + mapping per keyframe (first 20000)
  double registration_ms = 0.0, fusion_ms = 0.0, local_ba_ms = 0.0;  ///< totals per stage
  int64_t local_bas = 0;
};

struct BackendStats {
  std::map<AgentId, AgentCounters> agents;
  int64_t fusions = 0, loops = 0;
  int64_t global_ba_applied = 0, global_ba_aborted = 0, global_ba_stale = 0;
  int64_t keyframes_removed = 0;     ///< redundancy removal
  int64_t batches_rejected = 0;      ///< whole batches refused (protocol, max_agents)
  int64_t agent_slots_released = 0;  ///< idle agents' slots given to new agents
  std::vector<std::pair<int, double>> global_ba_seconds;  ///< (keyframes, seconds) per applied run
  PlaceMatcherStats place;
};

/// Work waiting in each stage (status displays, benchmarks).
struct QueueDepths {
  std::map<AgentId, size_t> agent_batches;
  std::map<AgentId, size_t> agent_bytes;  ///< ApproxBatchBytes of the batches waiting
  /// How long the oldest batch not yet registered (in process or waiting) has been in the
  /// back-end; 0 when the agent's queue is empty: its registration lag.
  std::map<AgentId, double> agent_lag_s;
  size_t place_recognition = 0;
  size_t global_ba_pending = 0;
  bool global_ba_running = false;
};

struct BackendStatus {
  BackendStats stats;
  QueueDepths queues;
  std::vector<AgentId> agents;  ///< every agent that submitted since the back-end started, ascending
  /// No stage had queued or running work when the status was taken (an idle-exit check;
  /// WaitUntilIdle() to wait for it).
  bool idle = true;
};

}  // namespace ccm
