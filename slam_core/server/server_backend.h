// The server back-end facade: the only thing ccm_server and ccm_replay see. A batch of one
// agent's data goes one way through named stages:
//   Submit (validate, per-agent queue) -> AgentRegistration (relative poses -> map, lambda)
//   -> ServerMapper (covisibility, point fusion, local BA, near-duplicates) -> PlaceMatcher
//   (database + verification + consistency) -> CloseLoop / FuseMaps -> global BA job
//   -> outgoing hooks (acks, the k covisible keyframes for the agent).
// The back-end owns no thread. The caller runs the stages: RunHandlerOnce(agent) on one
// thread per agent (several agents register into one merged map in parallel),
// RunPlaceRecognitionOnce on one thread (it also closes loops and fuses maps), and
// RunOptimizationOnce on one thread (global BA, then redundancy removal while BA is idle);
// or ProcessAllQueued on one thread for deterministic runs. Every public method is
// thread-safe. Lock order: see server_map.h; the back-end's own mutexes (queues, acks,
// stats) are leaves.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/exchange/server_map_data.h"
#include "slam_core/server/global_ba.h"
#include "slam_core/server/loop_closer.h"
#include "slam_core/server/map_fuser.h"
#include "slam_core/server/map_stack.h"
#include "slam_core/server/place_matcher.h"
#include "slam_core/server/redundancy.h"
#include "slam_core/server/registration.h"
#include "slam_core/server/server_mapper.h"

namespace ccm {

struct MapStackContents;

/// Something a user wants to see in a log or a summary.
struct ServerEvent {
  enum class Kind { kNewMap, kFusion, kLoop, kGlobalBa };
  Kind kind = Kind::kNewMap;
  double time_s = 0.0;       ///< seconds since the back-end started (wall clock)
  int64_t stamp_ns = 0;      ///< data time: the stamp of the keyframe that caused it
  AgentId agent = 0;         ///< whose keyframe caused it
  MapId map, other_map;      ///< fusion: kept, absorbed
  KeyframeId query, candidate;
  /// Loop / fusion: the verified camera-frame similarity p_query = S * p_candidate (what an
  /// evaluation compares with ground truth).
  Sim3 query_from_candidate;
  int keyframes = 0;         ///< size of the map afterwards
  double seconds = 0.0;      ///< how long the step took
  std::string detail;
};
const char* ServerEventKindName(ServerEvent::Kind kind);

struct AgentCounters {
  int64_t batches = 0;
  int64_t keyframes_registered = 0;
  int64_t keyframes_duplicate = 0;   ///< skipped as near-duplicates (anchored)
  int64_t keyframes_anchor_only = 0; ///< near-duplicates the agent sent as anchors only
  /// Keyframes whose links mostly disagreed, placed on the points their predecessor sees
  /// (an agent back at old points before the loop was closed); registration.cc RefinePose.
  int64_t keyframes_kept_on_track = 0;
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
  std::vector<std::pair<int, double>> global_ba_seconds;  ///< (keyframes, seconds) per applied run
  PlaceMatcherStats place;
};

/// Work waiting in each stage (status displays, benchmarks).
struct QueueDepths {
  std::map<AgentId, size_t> agent_batches;
  std::map<AgentId, size_t> agent_bytes;  ///< ApproxBatchBytes of the batches waiting
  size_t place_recognition = 0;
  size_t global_ba_pending = 0;
  bool global_ba_running = false;
};

struct AgentAcks {
  std::vector<KeyframeId> keyframes;
  std::vector<MapPointId> map_points;
};

struct ServerKeyframePose {
  KeyframeId id;
  MapId map;           ///< server map it is in
  MapId segment;       ///< the agent's VO segment
  int64_t stamp_ns = 0;
  SE3 world_from_cam;  ///< in that server map
  bool in_map = true;  ///< false: anchored (skipped or removed), pose through its anchor
};

struct MapSummary {
  MapId id;
  size_t keyframes = 0, map_points = 0, anchored = 0;
  std::set<AgentId> agents;
};

class ServerBackend {
 public:
  ServerBackend(std::shared_ptr<const Vocabulary> vocabulary, ServerOptions options);
  ~ServerBackend();
  ServerBackend(const ServerBackend&) = delete;
  ServerBackend& operator=(const ServerBackend&) = delete;

  /// Any thread. Validates every item (rejected ones are counted, the rest is queued); an
  /// agent beyond max_agents is refused, a batch for a full queue dropped (both counted).
  /// Returns the number of items rejected, -1 if the whole batch was refused or dropped.
  int Submit(AgentBatch batch);
  /// Called (from Submit's thread) the first time an agent submits: the runner starts its
  /// handler thread. Set before the first Submit.
  void SetNewAgentCallback(std::function<void(AgentId)> callback);

  /// Stage threads; each waits up to `timeout` for work, returns whether it did some.
  bool RunHandlerOnce(AgentId agent, std::chrono::milliseconds timeout);
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
  /// True when no stage has queued or running work.
  bool Idle() const;
  /// Blocks until Idle() (threaded runs, end of a replay).
  void WaitUntilIdle();
  /// Queues a global BA of `map` (e.g. a final one at the end of a replay).
  void ScheduleGlobalBa(MapId map);

  // Outgoing hooks.
  AgentAcks TakeAcks(AgentId agent);
  std::optional<ServerMapData> Neighbourhood(AgentId agent, KeyframeId reference_kf) const;

  // Inspection.
  BackendStats stats() const;
  QueueDepths queue_depths() const;
  std::vector<ServerEvent> events() const;
  std::vector<MapSummary> Maps() const;
  std::vector<AgentId> agents() const;
  /// Every keyframe of `agent` the server registered (anchored ones too), sorted by stamp.
  std::vector<ServerKeyframePose> AgentTrajectory(AgentId agent) const;
  MapStack& stack() { return stack_; }
  const MapStack& stack() const { return stack_; }
  const ServerOptions& options() const { return options_; }
  const Vocabulary& vocabulary() const { return *vocabulary_; }

  /// Persistence (map_persistence.h): maps, handlers and events; the database is rebuilt at
  /// load. Load falls back to the previous generation (path.prev) when `path` is unreadable
  /// or corrupt, and then says so in *warning.
  bool Save(const std::string& path, std::string* error) const;
  static std::unique_ptr<ServerBackend> Load(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                                             ServerOptions options, std::string* error,
                                             std::string* warning = nullptr);

 private:
  struct AgentQueue {
    std::deque<AgentBatch> batches;
    size_t bytes = 0;  ///< ApproxBatchBytes of the queued batches (max_queued_bytes_per_agent)
    std::set<uint64_t> segments;  ///< segment ids submitted (max_segments_per_agent)
    bool busy = false;
    std::unique_ptr<AgentRegistration> registration;
  };
  void ProcessBatch(AgentRegistration* reg, const AgentBatch& batch);
  void HandleDetection(const PlaceDetection& detection);
  void RequestGlobalBa(MapId map);
  bool RunRedundancyStep();
  bool RunOptimization(std::chrono::milliseconds timeout, bool respect_pause);
  void AddEvent(ServerEvent e);
  double Elapsed() const;
  /// After Load: the stack, handlers and events from the file, the database from its keyframes.
  void Restore(MapStackContents contents);

  std::shared_ptr<const Vocabulary> vocabulary_;
  const ServerOptions options_;
  const std::chrono::steady_clock::time_point start_;
  MapStack stack_;
  ServerMapper mapper_;
  PlaceMatcher matcher_;  // place-recognition thread (its database is thread-safe)

  mutable std::mutex queue_mutex_;  // agent queues; leaf
  std::condition_variable queue_cv_;
  std::map<AgentId, AgentQueue> queues_;
  std::function<void(AgentId)> on_new_agent_;

  mutable std::mutex pr_mutex_;  // place-recognition queue; leaf
  std::condition_variable pr_cv_;
  std::deque<KeyframeId> pr_queue_;
  bool pr_busy_ = false;

  mutable std::mutex opt_mutex_;  // optimization jobs; leaf
  std::condition_variable opt_cv_;
  std::set<MapId> ba_pending_;
  std::map<MapId, std::chrono::steady_clock::time_point> ba_not_before_;  ///< duty cycle per map
  MapId ba_running_;
  int64_t redundancy_budget_ = 0;  ///< steps earned by registered keyframes
  bool opt_busy_ = false;
  std::atomic<bool> abort_ba_{false};
  RedundancyRemover redundancy_;  // optimization thread

  // WaitUntilIdle sleeps on idle_cv_ under idle_mutex_ and evaluates Idle() (which takes the
  // three stage mutexes) while holding it: lock order idle_mutex_ -> stage mutex. Stages
  // call NotifyIdleChange() holding none of their mutexes.
  void NotifyIdleChange();
  mutable std::mutex idle_mutex_;
  std::condition_variable idle_cv_;
  size_t redundancy_next_ = 0;  // optimization thread: round-robin over maps
  std::atomic<bool> stopping_{false};

  mutable std::mutex acks_mutex_;  // leaf
  std::map<AgentId, AgentAcks> acks_;

  mutable std::mutex stats_mutex_;  // leaf
  BackendStats stats_;
  std::vector<ServerEvent> events_;
};

}  // namespace ccm
