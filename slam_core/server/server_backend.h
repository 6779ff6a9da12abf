// The server back-end facade: the only thing ccm_server, ccm_replay and the map view see. A
// batch of one agent's data goes one way through named stages:
//   Submit (validate; BackendScheduler: per-agent queue) -> AgentRegistration (relative
//   poses -> map, lambda) -> ServerMapper (covisibility, point fusion, local BA,
//   near-duplicates) -> PlaceMatcher (database + verification + consistency) -> CloseLoop /
//   FuseMaps -> global BA and RedundancyStage -> outgoing (acks, the k covisible
//   keyframes for the agent).
// The back-end owns no thread. The caller runs the stages: RunHandlerOnce(agent) on one
// thread per agent (several agents register into one merged map in parallel),
// RunPlaceRecognitionOnce on one thread (it also closes loops and fuses maps), and
// RunOptimizationOnce on one thread (global BA, then redundancy removal while BA is idle);
// or ProcessAllQueued on one thread for deterministic runs. Every public method is
// thread-safe. Readers get copies (Status()) or a read-only snapshot of the map stack
// (Snapshot()); persistence goes through Snapshot() and the restoring constructor
// (map_persistence.h).
//
// Lock order (docs/architecture.md): a stage's map work follows server_map.h (MapStack's
// mutex a leaf; structure mutexes of two maps in ascending id; Map internals; tables). The
// scheduler's mutexes (backend_scheduler.h) are never held while a stage works on a map.
// The facade's own mutexes (acks_mutex_, stats_mutex_, callback_mutex_, ba_regions_mutex_) are leaves: each is
// held only to copy or add a value, never together with another lock, never across a call.
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_set>
#include <vector>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/exchange/server_map_data.h"
#include "slam_core/server/backend_scheduler.h"
#include "slam_core/server/detection_stage.h"
#include "slam_core/server/backend_status.h"
#include "slam_core/server/map_stack_snapshot.h"
#include "slam_core/server/place_matcher.h"
#include "slam_core/server/redundancy.h"
#include "slam_core/server/server_mapper.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct AgentAcks {
  std::vector<KeyframeId> keyframes;
  std::vector<MapPointId> map_points;
};

class ServerBackend {
 public:
  ServerBackend(std::shared_ptr<const Vocabulary> vocabulary, ServerOptions options);
  /// Starts from `restored` (a loaded file, or a test's hand-built maps) instead of an
  /// empty stack: its maps, handlers and events; the place-recognition database is built
  /// from its keyframes with `vocabulary`.
  ServerBackend(std::shared_ptr<const Vocabulary> vocabulary, ServerOptions options, RestoredStack restored);
  ~ServerBackend();
  ServerBackend(const ServerBackend&) = delete;
  ServerBackend& operator=(const ServerBackend&) = delete;

  /// Any thread. Validates every item (rejected ones are counted, the rest is queued); an
  /// agent beyond max_agents is refused, a batch for a full queue dropped (both counted).
  /// Returns the number of items rejected, -1 if the whole batch was refused or dropped.
  int Submit(AgentBatch batch);
  /// Called (from Submit's thread) when an agent with no handler stage submits (its first
  /// batch, or its first after its slot was released): the runner starts its handler
  /// thread. Set before the first Submit.
  void SetNewAgentCallback(std::function<void(AgentId)> callback);

  /// Stage threads; each waits up to `timeout` for work, returns whether it did some.
  /// A handler stage whose agent holds no slot (released after ServerOptions::
  /// agent_slot_release_s idle) gets kAgentReleased and ends.
  enum class HandlerStep { kIdle, kProcessed, kAgentReleased };
  HandlerStep RunHandlerOnce(AgentId agent, std::chrono::milliseconds timeout);
  bool RunPlaceRecognitionOnce(std::chrono::milliseconds timeout);
  bool RunOptimizationOnce(std::chrono::milliseconds timeout);
  /// Wakes every waiting stage and aborts a running global BA (shutdown); stages return
  /// at once until Resume().
  void Stop();
  /// Clears Stop() once the stage threads are joined, so the back-end can be driven again
  /// (saved, processed on one thread, or given new threads).
  void Resume();
  /// One thread, fixed order: every queued batch, then place recognition, then the pending
  /// global BAs and redundancy steps. Deterministic for a given input order.
  void ProcessAllQueued();
  /// Blocks until no stage has queued or running work (threaded runs, end of a replay).
  void WaitUntilIdle();
  /// The end of a run (the agents fly no further): queues for every map of 3 keyframes or
  /// more the revisit sweep (RedundancyStage::SweepRevisits: the keyframes of repeated passes
  /// that revisit_settle_s held back leave as anchors) and then a global BA of the whole map,
  /// both on the optimization thread. Drive it with ProcessAllQueued or WaitUntilIdle.
  void ScheduleFinish();

  // Outgoing hooks.
  AgentAcks TakeAcks(AgentId agent);
  /// The agent's neighbourhood; keyframes in `held` (the agent has them) go as poses only.
  std::optional<ServerMapData> Neighbourhood(AgentId agent, KeyframeId reference_kf,
                                             const std::unordered_set<KeyframeId>* held = nullptr) const;

  // Inspection.
  /// Counters, queue depths, agents, idleness: copies.
  BackendStatus Status() const;
  /// The live maps (read-only), handlers and events (map_stack_snapshot.h); what the map
  /// view, the run outputs and persistence read.
  MapStackSnapshot Snapshot() const;

 private:
  void ProcessBatch(AgentRegistration* reg, const AgentBatch& batch);
  void HandleDetection(const PlaceDetection& detection);
  bool RunOptimization(std::chrono::milliseconds timeout, bool respect_pause);
  void RunGlobalBa(MapId map);
  void RunRedundancyStep();
  void AddEvent(ServerEvent e);
  double Elapsed() const;

  std::shared_ptr<const Vocabulary> vocabulary_;
  const ServerOptions options_;
  const std::chrono::steady_clock::time_point start_;
  std::shared_ptr<MapStack> stack_;
  ServerMapper mapper_;
  PlaceMatcher matcher_;  // place-recognition thread (its database is thread-safe)
  BackendScheduler scheduler_;
  RedundancyStage redundancy_;  // optimization thread
  DetectionStage detection_;    // place-recognition thread

  mutable std::mutex callback_mutex_;  // leaf
  std::function<void(AgentId)> on_new_agent_;

  mutable std::mutex acks_mutex_;  // leaf
  std::map<AgentId, AgentAcks> acks_;

  // Where the next global BA of a map looks first: the keyframes of the loops and fusions
  // that asked for it (GlobalBaOptions::region_seeds); `full` after ScheduleFinish.
  struct BaRegion {
    bool full = false;
    bool sweep_revisits = false;  ///< the end of the run: RedundancyStage::SweepRevisits first
    std::vector<KeyframeId> seeds;
    void Add(const BaRegion& other) {
      full = full || other.full;
      sweep_revisits = sweep_revisits || other.sweep_revisits;
      seeds.insert(seeds.end(), other.seeds.begin(), other.seeds.end());
    }
  };
  mutable std::mutex ba_regions_mutex_;  // leaf
  std::map<MapId, BaRegion> ba_regions_;

  mutable std::mutex stats_mutex_;  // leaf
  BackendStats stats_;
  std::vector<ServerEvent> events_;
};

}  // namespace ccm
