// The back-end's work queues and the waits on them, apart from the SLAM the stages do:
//  * one queue of batches per agent, bounded in batches, bytes and map segments, with the
//    agent's registration state (one handler thread per agent takes from it); max_agents
//    such slots, and a slot whose agent sent nothing for release_idle_after is given back
//    when a new agent needs one (its maps, handlers and segment budget stay; its handler
//    stage is told so and ends; if it comes back it gets a fresh queue and registration);
//  * the place-recognition queue of registered keyframes;
//  * the optimization jobs: global BA requests (one per map, each map paused after an
//    applied run for a multiple of its duration, held while a loop or fusion of it is
//    applied) and redundancy steps earned by registered keyframes.
// A stage takes work (Take*, waiting up to a timeout), does it with no scheduler lock held,
// and reports it done (*Done); Idle() / WaitUntilIdle() see queued and running work. Owns no
// thread and no map; thread-safe.
//
// Lock order: idle_mutex_ -> {queue_mutex_, pr_mutex_, opt_mutex_} (WaitUntilIdle evaluates
// Idle() under idle_mutex_). The three stage mutexes are leaves: never two at once, and
// nothing outside this class is called while one is held except Admit's
// make_registration, which must take no lock of the back-end's.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <vector>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/server/backend_status.h"

namespace ccm {

class AgentRegistration;

class BackendScheduler {
 public:
  using Clock = std::chrono::steady_clock;
  struct Limits {
    int max_agents = 0;
    int max_batches_per_agent = 0;
    size_t max_bytes_per_agent = 0;  ///< a batch is queued into an empty queue whatever its size
    int max_segments_per_agent = 0;
    /// A slot idle this long is released for a new agent; zero: never.
    Clock::duration release_idle_after = Clock::duration::zero();
  };
  explicit BackendScheduler(Limits limits);
  ~BackendScheduler();  // out of line: AgentRegistration is incomplete here
  BackendScheduler(const BackendScheduler&) = delete;
  BackendScheduler& operator=(const BackendScheduler&) = delete;

  enum class Admission { kQueued, kAgentRefused, kQueueFull, kQueueBytes, kSegments };
  /// Queues `batch` unless a limit refuses it (checked in the order of the enum). The first
  /// batch of an agent creates its queue with the registration `make_registration` returns,
  /// under the queue lock, so no handler ever sees the queue without it. *first_of_agent:
  /// queued, and the agent has no handler stage yet: start one (an empty batch is not
  /// queued but counts). An agent beyond max_agents first frees idle slots.
  Admission Admit(AgentBatch batch, const std::function<std::unique_ptr<AgentRegistration>()>& make_registration,
                  bool* first_of_agent);

  /// Handler stage of `agent`: its oldest batch and its registration, once no other thread
  /// handles the agent. nullopt after `timeout`, once stopped, or at once when the agent
  /// holds no slot (never admitted, or released): then *released is set and the stage
  /// should end; a later Admit of the agent asks for a new one.
  struct AgentWork {
    AgentBatch batch;
    AgentRegistration* registration = nullptr;
  };
  std::optional<AgentWork> TakeBatch(AgentId agent, std::chrono::milliseconds timeout, bool* released = nullptr);
  void BatchDone(AgentId agent);

  void QueueForPlaceRecognition(const std::vector<KeyframeId>& keyframes);
  std::optional<KeyframeId> TakeKeyframe(std::chrono::milliseconds timeout);
  void KeyframeDone();

  void EarnRedundancySteps(int64_t steps);
  void RequestGlobalBa(MapId map);
  /// A loop or fusion of these maps is about to be applied: a running global BA of either
  /// would come back stale, so it is told to stop now, and no global BA of either starts
  /// (a loop solves its pose graph with the map unlocked, half corrected) until
  /// ReleaseGlobalBaHold().
  void HoldGlobalBaOf(MapId a, MapId b);
  void ReleaseGlobalBaHold();
  /// A map fused into another: its pending global BA is dropped.
  void ForgetGlobalBa(MapId map);
  /// The next optimization job: a global BA of `global_ba` whose pause is over
  /// (`respect_pause` false: any pending one), else a redundancy step (global_ba invalid).
  struct OptimizationJob {
    MapId global_ba;
  };
  std::optional<OptimizationJob> TakeOptimizationJob(std::chrono::milliseconds timeout, bool respect_pause);
  /// Set while a global BA runs; AbortGlobalBaOf and Stop set it.
  const std::atomic<bool>* abort_flag() const { return &abort_ba_; }
  /// A global BA of `map` ended: `retry` (aborted or stale, map still there) queues it again
  /// unless stopping; `pause` > 0 (applied) holds the map's next one back that long.
  void GlobalBaDone(MapId map, bool retry, Clock::duration pause);
  /// After GlobalBaDone or a redundancy step, once its results are recorded.
  void OptimizationDone();

  /// Wakes every waiting stage and aborts a running global BA; Take* return nullopt until
  /// Resume().
  void Stop();
  void Resume();
  bool stopping() const { return stopping_; }

  bool Idle() const;
  void WaitUntilIdle();
  QueueDepths Depths() const;
  /// Every agent admitted since the start, released ones included, ascending.
  std::vector<AgentId> Agents() const;
  int64_t slots_released() const;

 private:
  struct AgentQueue {
    std::deque<AgentBatch> batches;
    std::deque<Clock::time_point> arrivals;  ///< when each queued batch was admitted
    size_t bytes = 0;  ///< ApproxBatchBytes of the queued batches
    bool busy = false;
    Clock::time_point busy_arrival;  ///< admission time of the batch being processed
    Clock::time_point last_admitted;
    std::unique_ptr<AgentRegistration> registration;
  };
  /// Frees the slots idle for release_idle_after (queue lock held).
  void ReleaseIdleSlotsLocked();
  /// Stages call it holding none of their mutexes.
  void NotifyIdleChange();

  const Limits limits_;
  std::atomic<bool> stopping_{false};

  mutable std::mutex queue_mutex_;  // agent queues; leaf
  std::condition_variable queue_cv_;
  std::map<AgentId, AgentQueue> queues_;  ///< agents holding a slot
  std::map<AgentId, std::set<uint64_t>> segments_;  ///< segment ids each agent submitted (outlives its slot)
  std::set<AgentId> known_;  ///< every agent admitted since the start
  std::set<AgentId> with_handler_;  ///< agents whose handler stage was asked for and has not ended
  int64_t slots_released_ = 0;

  mutable std::mutex pr_mutex_;  // place-recognition queue; leaf
  std::condition_variable pr_cv_;
  std::deque<KeyframeId> pr_queue_;
  bool pr_busy_ = false;

  mutable std::mutex opt_mutex_;  // optimization jobs; leaf
  std::condition_variable opt_cv_;
  std::set<MapId> ba_pending_;
  std::set<MapId> ba_held_;  ///< maps a detection is being applied to
  std::map<MapId, Clock::time_point> ba_not_before_;  ///< duty cycle per map
  MapId ba_running_;
  int64_t redundancy_budget_ = 0;
  bool opt_busy_ = false;
  std::atomic<bool> abort_ba_{false};

  mutable std::mutex idle_mutex_;  // before the stage mutexes
  std::condition_variable idle_cv_;
};

}  // namespace ccm
