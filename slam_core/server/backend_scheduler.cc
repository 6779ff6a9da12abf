#include "slam_core/server/backend_scheduler.h"

#include <algorithm>
#include <utility>

#include "slam_core/server/registration.h"

namespace ccm {
namespace {

// Every segment id a batch names (each becomes a server map when registered).
std::set<uint64_t> SegmentsOf(const AgentBatch& b) {
  std::set<uint64_t> out;
  if (b.segment.valid()) out.insert(b.segment.packed());
  for (const KeyframeData& k : b.keyframes) out.insert(k.segment.packed());
  for (const MapPointData& m : b.map_points) out.insert(m.segment.packed());
  for (const KeyframePoseUpdate& u : b.keyframe_updates) out.insert(u.segment.packed());
  return out;
}

}  // namespace

BackendScheduler::BackendScheduler(Limits limits) : limits_(limits) {}

BackendScheduler::~BackendScheduler() = default;

BackendScheduler::Admission BackendScheduler::Admit(
    AgentBatch batch, const std::function<std::unique_ptr<AgentRegistration>()>& make_registration,
    bool* first_of_agent) {
  const AgentId agent = batch.agent;
  *first_of_agent = false;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    const bool is_new = !queues_.count(agent);
    if (is_new && static_cast<int>(queues_.size()) >= limits_.max_agents) ReleaseIdleSlotsLocked();
    if (is_new && static_cast<int>(queues_.size()) >= limits_.max_agents) return Admission::kAgentRefused;
    AgentQueue& q = queues_[agent];
    if (is_new) q.registration = make_registration();
    // Registration opens a map for the segment of every item, not only the batch's.
    std::set<uint64_t>& segments = segments_[agent];
    std::set<uint64_t> fresh;
    for (const uint64_t s : SegmentsOf(batch)) {
      if (!segments.count(s)) fresh.insert(s);
    }
    const size_t bytes = ApproxBatchBytes(batch);
    Admission refusal = Admission::kQueued;
    if (static_cast<int>(q.batches.size()) >= limits_.max_batches_per_agent) {
      refusal = Admission::kQueueFull;
    } else if (!q.batches.empty() && q.bytes + bytes > limits_.max_bytes_per_agent) {
      refusal = Admission::kQueueBytes;
    } else if (static_cast<int>(segments.size() + fresh.size()) > limits_.max_segments_per_agent) {
      refusal = Admission::kSegments;
    }
    if (refusal != Admission::kQueued) {
      // An agent whose first batch is refused is not admitted at all: keeping its queue
      // would take a slot and make its next batch look like a known agent's, which never
      // starts a handler.
      if (is_new) queues_.erase(agent);
      if (segments.empty()) segments_.erase(agent);
      return refusal;
    }
    segments.insert(fresh.begin(), fresh.end());
    q.last_admitted = Clock::now();
    if (!batch.empty()) {
      q.batches.push_back(std::move(batch));
      q.arrivals.push_back(q.last_admitted);
      q.bytes += bytes;
    }
    known_.insert(agent);
    // A released agent whose handler stage has not noticed yet keeps that one.
    *first_of_agent = is_new && with_handler_.insert(agent).second;
  }
  // Also wakes the handler stages of released agents, which then end.
  queue_cv_.notify_all();
  return Admission::kQueued;
}

void BackendScheduler::ReleaseIdleSlotsLocked() {
  if (limits_.release_idle_after <= Clock::duration::zero()) return;
  const auto now = Clock::now();
  for (auto it = queues_.begin(); it != queues_.end();) {
    const AgentQueue& q = it->second;
    if (q.batches.empty() && !q.busy && now - q.last_admitted >= limits_.release_idle_after) {
      it = queues_.erase(it);
      ++slots_released_;
    } else {
      ++it;
    }
  }
}

std::optional<BackendScheduler::AgentWork> BackendScheduler::TakeBatch(AgentId agent,
                                                                       std::chrono::milliseconds timeout,
                                                                       bool* released) {
  std::unique_lock<std::mutex> lock(queue_mutex_);
  auto ready = [&] {
    const auto it = queues_.find(agent);
    return stopping_ || it == queues_.end() || (!it->second.batches.empty() && !it->second.busy);
  };
  if (!queue_cv_.wait_for(lock, timeout, ready) || stopping_) return std::nullopt;
  const auto it = queues_.find(agent);
  if (it == queues_.end()) {
    with_handler_.erase(agent);
    if (released != nullptr) *released = true;
    return std::nullopt;
  }
  AgentQueue& q = it->second;
  AgentWork work{std::move(q.batches.front()), q.registration.get()};
  q.batches.pop_front();
  q.busy_arrival = q.arrivals.front();
  q.arrivals.pop_front();
  q.bytes -= ApproxBatchBytes(work.batch);
  q.busy = true;
  return work;
}

void BackendScheduler::BatchDone(AgentId agent) {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    queues_.at(agent).busy = false;
  }
  queue_cv_.notify_all();
  NotifyIdleChange();
}

void BackendScheduler::QueueForPlaceRecognition(const std::vector<KeyframeId>& keyframes) {
  if (keyframes.empty()) return;
  {
    std::lock_guard<std::mutex> lock(pr_mutex_);
    pr_queue_.insert(pr_queue_.end(), keyframes.begin(), keyframes.end());
  }
  pr_cv_.notify_all();
}

std::optional<KeyframeId> BackendScheduler::TakeKeyframe(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(pr_mutex_);
  if (!pr_cv_.wait_for(lock, timeout, [&] { return stopping_ || !pr_queue_.empty(); }) || stopping_) {
    return std::nullopt;
  }
  const KeyframeId kf = pr_queue_.front();
  pr_queue_.pop_front();
  pr_busy_ = true;
  return kf;
}

void BackendScheduler::KeyframeDone() {
  {
    std::lock_guard<std::mutex> lock(pr_mutex_);
    pr_busy_ = false;
  }
  NotifyIdleChange();
}

void BackendScheduler::EarnRedundancySteps(int64_t steps) {
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    redundancy_budget_ += steps;
  }
  opt_cv_.notify_all();
}

void BackendScheduler::RequestGlobalBa(MapId map) {
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    ba_pending_.insert(map);
  }
  opt_cv_.notify_all();
}

void BackendScheduler::HoldGlobalBaOf(MapId a, MapId b) {
  std::lock_guard<std::mutex> lock(opt_mutex_);
  if (ba_running_.valid() && (ba_running_ == a || ba_running_ == b)) abort_ba_ = true;
  ba_held_ = {a, b};
}

void BackendScheduler::ReleaseGlobalBaHold() {
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    ba_held_.clear();
  }
  opt_cv_.notify_all();
}

void BackendScheduler::ForgetGlobalBa(MapId map) {
  std::lock_guard<std::mutex> lock(opt_mutex_);
  ba_pending_.erase(map);
}

std::optional<BackendScheduler::OptimizationJob> BackendScheduler::TakeOptimizationJob(
    std::chrono::milliseconds timeout, bool respect_pause) {
  std::unique_lock<std::mutex> lock(opt_mutex_);
  // A global BA may start once its map's pause since the last one is over (duty cycle).
  auto next_ba = [&]() -> std::optional<std::pair<MapId, Clock::time_point>> {
    std::optional<std::pair<MapId, Clock::time_point>> best;
    for (const MapId m : ba_pending_) {
      if (ba_held_.count(m)) continue;
      const auto it = ba_not_before_.find(m);
      const Clock::time_point t = respect_pause && it != ba_not_before_.end() ? it->second : Clock::time_point();
      if (!best || t < best->second) best = std::make_pair(m, t);
    }
    return best;
  };
  auto ready = [&] {
    const auto n = next_ba();
    return stopping_ || redundancy_budget_ > 0 || (n && n->second <= Clock::now());
  };
  const auto deadline = Clock::now() + timeout;
  while (!ready()) {
    const auto n = next_ba();
    const auto until = n ? std::min(deadline, n->second) : deadline;
    if (Clock::now() >= deadline) return std::nullopt;
    opt_cv_.wait_until(lock, until);
  }
  if (stopping_) return std::nullopt;
  opt_busy_ = true;
  OptimizationJob job;
  const auto n = next_ba();
  if (n && n->second <= Clock::now()) {
    job.global_ba = n->first;
    ba_pending_.erase(job.global_ba);
    ba_running_ = job.global_ba;
    abort_ba_ = false;
  } else {
    --redundancy_budget_;
  }
  return job;
}

void BackendScheduler::GlobalBaDone(MapId map, bool retry, Clock::duration pause) {
  std::lock_guard<std::mutex> lock(opt_mutex_);
  ba_running_ = MapId();
  if (retry && !stopping_) ba_pending_.insert(map);
  if (pause > Clock::duration::zero()) ba_not_before_[map] = Clock::now() + pause;
}

void BackendScheduler::OptimizationDone() {
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    opt_busy_ = false;
  }
  opt_cv_.notify_all();
  NotifyIdleChange();
}

void BackendScheduler::Stop() {
  stopping_ = true;
  abort_ba_ = true;
  // Taking each mutex once orders the flag before every waiter's next predicate check.
  { std::lock_guard<std::mutex> a(queue_mutex_); }
  { std::lock_guard<std::mutex> b(pr_mutex_); }
  { std::lock_guard<std::mutex> c(opt_mutex_); }
  queue_cv_.notify_all();
  pr_cv_.notify_all();
  opt_cv_.notify_all();
  NotifyIdleChange();
}

void BackendScheduler::Resume() {
  stopping_ = false;
  abort_ba_ = false;
}

bool BackendScheduler::Idle() const {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    for (const auto& [a, q] : queues_) {
      if (!q.batches.empty() || q.busy) return false;
    }
  }
  {
    std::lock_guard<std::mutex> lock(pr_mutex_);
    if (!pr_queue_.empty() || pr_busy_) return false;
  }
  std::lock_guard<std::mutex> lock(opt_mutex_);
  return ba_pending_.empty() && !opt_busy_ && redundancy_budget_ == 0;
}

void BackendScheduler::NotifyIdleChange() {
  { std::lock_guard<std::mutex> lock(idle_mutex_); }
  idle_cv_.notify_all();
}

void BackendScheduler::WaitUntilIdle() {
  std::unique_lock<std::mutex> lock(idle_mutex_);
  idle_cv_.wait(lock, [this] { return stopping_ || Idle(); });
}

QueueDepths BackendScheduler::Depths() const {
  QueueDepths d;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    const auto now = Clock::now();
    for (const auto& [a, q] : queues_) {
      d.agent_batches[a] = q.batches.size() + (q.busy ? 1 : 0);
      d.agent_bytes[a] = q.bytes;
      // The oldest batch not yet done: the one in process, else the queue's first.
      const Clock::time_point* oldest = q.busy ? &q.busy_arrival : q.arrivals.empty() ? nullptr : &q.arrivals.front();
      d.agent_lag_s[a] = oldest ? std::chrono::duration<double>(now - *oldest).count() : 0.0;
    }
  }
  {
    std::lock_guard<std::mutex> lock(pr_mutex_);
    d.place_recognition = pr_queue_.size() + (pr_busy_ ? 1 : 0);
  }
  std::lock_guard<std::mutex> lock(opt_mutex_);
  d.global_ba_pending = ba_pending_.size();
  d.global_ba_running = ba_running_.valid();
  return d;
}

std::vector<AgentId> BackendScheduler::Agents() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return std::vector<AgentId>(known_.begin(), known_.end());
}

int64_t BackendScheduler::slots_released() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return slots_released_;
}

}  // namespace ccm
