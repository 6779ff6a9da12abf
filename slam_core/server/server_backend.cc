#include "slam_core/server/server_backend.h"

#include <algorithm>
#include <shared_mutex>

#include "slam_core/server/global_ba.h"
#include "slam_core/server/outgoing.h"
#include "slam_core/server/registration.h"

namespace ccm {
namespace {

using Clock = std::chrono::steady_clock;
constexpr size_t kMaxTimingSamples = 20000;

// Removes items that fail validation; returns how many and the first reason.
template <typename T, typename Fn>
int Filter(std::vector<T>* items, Fn validate, std::string* first_error) {
  int rejected = 0;
  items->erase(std::remove_if(items->begin(), items->end(),
                              [&](const T& item) {
                                const std::string e = validate(item);
                                if (e.empty()) return false;
                                if (first_error->empty()) *first_error = e;
                                ++rejected;
                                return true;
                              }),
               items->end());
  return rejected;
}

// The live map holding `kf`, locked shared; empty if none.
SharedMapLock LockMapOf(const MapStack& stack, KeyframeId kf) {
  for (int attempt = 0; attempt < 8; ++attempt) {
    auto map = stack.MapHolding(kf);
    if (!map) return {};
    std::shared_lock<WriterPreferringMutex> lock(map->structure_mutex());
    if (!map->retired()) return {std::move(map), std::move(lock)};
  }
  return {};
}

BackendScheduler::Limits LimitsOf(const ServerOptions& o) {
  BackendScheduler::Limits l;
  l.max_agents = o.max_agents;
  l.max_batches_per_agent = o.max_queued_batches_per_agent;
  l.max_bytes_per_agent = o.max_queued_bytes_per_agent;
  l.max_segments_per_agent = o.max_segments_per_agent;
  l.release_idle_after = std::chrono::duration_cast<BackendScheduler::Clock::duration>(
      std::chrono::duration<double>(o.agent_slot_release_s));
  return l;
}

}  // namespace

ServerBackend::ServerBackend(std::shared_ptr<const Vocabulary> vocabulary, ServerOptions options)
    : ServerBackend(std::move(vocabulary), std::move(options), RestoredStack{}) {}

ServerBackend::ServerBackend(std::shared_ptr<const Vocabulary> vocabulary, ServerOptions options,
                             RestoredStack restored)
    : vocabulary_(std::move(vocabulary)),
      options_(std::move(options)),
      start_(Clock::now()),
      stack_(restored.stack ? std::move(restored.stack) : std::make_shared<MapStack>(options_.map)),
      mapper_(options_.mapping),
      matcher_(vocabulary_, options_.place, stack_.get()),
      scheduler_(LimitsOf(options_)),
      redundancy_(options_.redundancy, stack_.get()),
      detection_(stack_.get(), options_,
                 {[this](MapId map) { matcher_.OnLoopClosed(map); },
                  [this](MapId absorbed, MapId kept) { matcher_.OnMapsFused(absorbed, kept); }}),
      events_(std::move(restored.events)) {
  for (const auto& m : stack_->Maps()) {
    std::shared_lock<WriterPreferringMutex> lock(m->structure_mutex());
    for (const auto& kf : m->map().keyframes()) matcher_.AddToDatabase(*kf, m->id());
  }
}

ServerBackend::~ServerBackend() { Stop(); }

double ServerBackend::Elapsed() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

void ServerBackend::SetNewAgentCallback(std::function<void(AgentId)> callback) {
  std::lock_guard<std::mutex> lock(callback_mutex_);
  on_new_agent_ = std::move(callback);
}

int ServerBackend::Submit(AgentBatch batch) {
  const AgentId agent = batch.agent;
  std::string error;
  int rejected = 0;
  rejected += Filter(&batch.keyframes, [&](const KeyframeData& k) { return ValidateKeyframeData(k, agent); }, &error);
  rejected += Filter(&batch.map_points, [&](const MapPointData& m) { return ValidateMapPointData(m, agent); }, &error);
  rejected += Filter(&batch.keyframe_updates,
                     [&](const KeyframePoseUpdate& u) { return ValidateKeyframePoseUpdate(u, agent); }, &error);
  rejected += Filter(&batch.map_point_updates,
                     [&](const MapPointPositionUpdate& u) { return ValidateMapPointPositionUpdate(u, agent); }, &error);
  using Admission = BackendScheduler::Admission;
  bool first_of_agent = false;
  // The server's own id is never an agent's: refused like an agent beyond max_agents.
  const Admission admission =
      agent == kServerAgent
          ? Admission::kAgentRefused
          : scheduler_.Admit(
                std::move(batch),
                [&] { return std::make_unique<AgentRegistration>(agent, stack_.get(), options_.registration); },
                &first_of_agent);
  if (admission != Admission::kQueued) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    if (admission == Admission::kAgentRefused) {
      ++stats_.batches_rejected;
    } else if (admission == Admission::kSegments) {
      AgentCounters& c = stats_.agents[agent];
      ++c.segments_refused;
      c.last_rejection = "more than max_segments_per_agent (" + std::to_string(options_.max_segments_per_agent) +
                         ") map segments";
    } else {
      AgentCounters& c = stats_.agents[agent];
      ++c.batches_dropped;
      if (admission == Admission::kQueueBytes) {
        c.last_rejection = "queue over max_queued_bytes_per_agent (" +
                           std::to_string(options_.max_queued_bytes_per_agent >> 20) + " MiB)";
      }
    }
    return -1;
  }
  if (rejected > 0) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    AgentCounters& c = stats_.agents[agent];
    c.rejected += rejected;
    c.last_rejection = error;
  }
  if (first_of_agent) {
    std::function<void(AgentId)> callback;
    {
      std::lock_guard<std::mutex> lock(callback_mutex_);
      callback = on_new_agent_;
    }
    if (callback) callback(agent);
  }
  return rejected;
}

ServerBackend::HandlerStep ServerBackend::RunHandlerOnce(AgentId agent, std::chrono::milliseconds timeout) {
  bool released = false;
  const auto work = scheduler_.TakeBatch(agent, timeout, &released);
  if (!work) return released ? HandlerStep::kAgentReleased : HandlerStep::kIdle;
  ProcessBatch(work->registration, work->batch);
  scheduler_.BatchDone(agent);
  return HandlerStep::kProcessed;
}

void ServerBackend::ProcessBatch(AgentRegistration* reg, const AgentBatch& batch) {
  const auto t0 = Clock::now();
  const RegistrationReport report = reg->Register(batch);
  const double registration_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const double per_kf_registration = report.keyframes.empty() ? 0.0 : registration_ms / report.keyframes.size();
  std::vector<KeyframeId> for_place_recognition;
  std::vector<double> kf_ms;
  int skipped = 0, local_bas = 0;
  double fusion_ms = 0.0, local_ba_ms = 0.0;
  // Keyframes registered before their points wait for them (RegisteredKeyframe::deferred);
  // those whose points have come are mapped and queried now.
  std::vector<KeyframeId> due;
  int deferred = 0;
  for (const RegisteredKeyframe& r : report.keyframes) {
    if (r.deferred) {
      ++deferred;
    } else {
      due.push_back(r.id);
    }
  }
  due.insert(due.end(), report.completed.begin(), report.completed.end());
  for (const KeyframeId id : due) {
    const auto t1 = Clock::now();
    SharedMapLock locked = LockMapOf(*stack_, id);
    if (!locked.map) continue;
    const auto kf = locked.map->map().keyframe(id);
    if (!kf) continue;
    const ServerMappingReport m = mapper_.Process(locked.map.get(), kf);
    fusion_ms += m.fusion_ms;
    local_ba_ms += m.local_ba_ms;
    local_bas += m.local_ba;
    if (m.skipped) {
      ++skipped;
    } else {
      for_place_recognition.push_back(id);
    }
    kf_ms.push_back(per_kf_registration + std::chrono::duration<double, std::milli>(Clock::now() - t1).count());
  }
  for (const MapId m : report.new_maps) {
    ServerEvent e;
    e.kind = ServerEvent::Kind::kNewMap;
    e.time_s = Elapsed();
    e.agent = reg->agent();
    e.map = m;
    e.stamp_ns = batch.keyframes.empty() ? batch.stamp_ns : batch.keyframes.front().stamp_ns;
    e.detail = "segment " + std::to_string(batch.segment.counter()) + " of agent " + std::to_string(reg->agent());
    AddEvent(e);
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    AgentCounters& c = stats_.agents[reg->agent()];
    ++c.batches;
    c.keyframes_registered += static_cast<int64_t>(report.keyframes.size());
    c.keyframes_duplicate += skipped;
    c.keyframes_anchor_only += report.anchors_registered + report.anchors_dropped;
    c.keyframes_kept_on_track += report.kept_on_track;
    c.keyframes_deferred += deferred;
    c.refinements_refused += report.implausible_refinements;
    c.points_registered += report.points_registered;
    c.updates_applied += report.keyframe_updates_applied + report.point_updates_applied;
    c.updates_ignored += report.updates_ignored;
    c.registration_ms += registration_ms;
    c.fusion_ms += fusion_ms;
    c.local_ba_ms += local_ba_ms;
    c.local_bas += local_bas;
    for (const double ms : kf_ms) {
      if (c.keyframe_ms.size() < kMaxTimingSamples) c.keyframe_ms.push_back(ms);
    }
  }
  // Acks after the counters: whoever sees an ack then sees the registration in the stats
  // (the daemon's autosave compares them to tell persisted acks, docs/protocol.md).
  {
    std::lock_guard<std::mutex> lock(acks_mutex_);
    AgentAcks& a = acks_[reg->agent()];
    a.keyframes.insert(a.keyframes.end(), report.acked_keyframes.begin(), report.acked_keyframes.end());
    a.map_points.insert(a.map_points.end(), report.acked_points.begin(), report.acked_points.end());
  }
  scheduler_.QueueForPlaceRecognition(for_place_recognition);
  if (options_.redundancy.enabled && !report.keyframes.empty()) {
    scheduler_.EarnRedundancySteps(static_cast<int64_t>(report.keyframes.size()));
  }
}

bool ServerBackend::RunPlaceRecognitionOnce(std::chrono::milliseconds timeout) {
  const auto kf = scheduler_.TakeKeyframe(timeout);
  if (!kf) return false;
  if (const auto detection = matcher_.Process(*kf)) HandleDetection(*detection);
  scheduler_.KeyframeDone();
  return true;
}

void ServerBackend::HandleDetection(const PlaceDetection& d) {
  scheduler_.HoldGlobalBaOf(d.query_map, d.candidate_map);
  DetectionOutcome outcome = detection_.Handle(d, Elapsed());
  if (outcome.event) {
    if (outcome.forget.valid()) scheduler_.ForgetGlobalBa(outcome.forget);
    if (outcome.optimize.valid()) {
      {
        std::lock_guard<std::mutex> lock(ba_regions_mutex_);
        BaRegion& region = ba_regions_[outcome.optimize];
        region.seeds.push_back(d.query);
        region.seeds.push_back(d.candidate);
        if (outcome.forget.valid()) {  // the absorbed map's wish goes with its keyframes
          const auto absorbed = ba_regions_.find(outcome.forget);
          if (absorbed != ba_regions_.end()) {
            region.Add(absorbed->second);
            ba_regions_.erase(absorbed);
          }
        }
      }
      scheduler_.RequestGlobalBa(outcome.optimize);
    }
  }
  scheduler_.ReleaseGlobalBaHold();
  if (!outcome.event) return;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++(outcome.event->kind == ServerEvent::Kind::kLoop ? stats_.loops : stats_.fusions);
  }
  AddEvent(std::move(*outcome.event));
}

void ServerBackend::ScheduleFinish() {
  for (const MapSummary& m : Snapshot().Summaries()) {
    if (m.keyframes < 3) continue;
    {
      std::lock_guard<std::mutex> lock(ba_regions_mutex_);
      BaRegion& region = ba_regions_[m.id];
      region.full = true;
      region.sweep_revisits = true;
    }
    scheduler_.RequestGlobalBa(m.id);
  }
}

bool ServerBackend::RunOptimizationOnce(std::chrono::milliseconds timeout) { return RunOptimization(timeout, true); }

bool ServerBackend::RunOptimization(std::chrono::milliseconds timeout, bool respect_pause) {
  const auto job = scheduler_.TakeOptimizationJob(timeout, respect_pause);
  if (!job) return false;
  if (job->global_ba.valid()) {
    RunGlobalBa(job->global_ba);
  } else {
    RunRedundancyStep();
  }
  scheduler_.OptimizationDone();
  return true;
}

void ServerBackend::RunGlobalBa(MapId map) {
  GlobalBaReport r;
  BaRegion region;
  {
    std::lock_guard<std::mutex> lock(ba_regions_mutex_);
    const auto it = ba_regions_.find(map);
    if (it != ba_regions_.end()) region = std::move(it->second), ba_regions_.erase(it);
  }
  if (region.sweep_revisits) {
    const auto removed = redundancy_.SweepRevisits(map, [this](KeyframeId id) { matcher_.OnKeyframeErased(id); });
    region.sweep_revisits = false;  // done, also if the BA below is retried
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.keyframes_removed += static_cast<int64_t>(removed.size());
  }
  if (const auto smap = stack_->GetMap(map)) {
    GlobalBaOptions o;
    o.iterations = options_.optimization.global_ba_iterations;
    o.threads = options_.optimization.global_ba_threads;
    o.linear_solver = options_.optimization.global_ba_solver;
    o.max_free_keyframes = options_.optimization.global_ba_max_free_keyframes;
    o.min_parallax_deg = options_.optimization.global_ba_min_parallax_deg;
    o.low_parallax_inverse_depth = options_.optimization.global_ba_low_parallax_inverse_depth;
    if (!region.full) o.region_seeds = region.seeds;  // none: the whole map
    r = RunGlobalBundleAdjustment(smap, o, scheduler_.abort_flag());
  }
  const bool applied = r.outcome == GlobalBaReport::Outcome::kApplied;
  const double seconds = r.snapshot_s + r.solve_s + r.write_back_s;
  const bool retry = (r.outcome == GlobalBaReport::Outcome::kAborted || r.outcome == GlobalBaReport::Outcome::kStale) &&
                     stack_->GetMap(map) != nullptr;
  // Duty cycle: the map's next global BA waits global_ba_pause_factor x this one's time.
  const auto pause = applied ? std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                                   options_.optimization.global_ba_pause_factor * seconds))
                             : Clock::duration::zero();
  if (retry) {  // the same wish again
    std::lock_guard<std::mutex> lock(ba_regions_mutex_);
    ba_regions_[map].Add(region);
  }
  scheduler_.GlobalBaDone(map, retry, pause);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    if (applied) {
      ++stats_.global_ba_applied;
      stats_.global_ba_seconds.emplace_back(r.keyframes, seconds);
    }
    stats_.global_ba_aborted += r.outcome == GlobalBaReport::Outcome::kAborted;
    stats_.global_ba_stale += r.outcome == GlobalBaReport::Outcome::kStale;
  }
  if (!applied) return;
  ServerEvent e;
  e.kind = ServerEvent::Kind::kGlobalBa;
  e.time_s = Elapsed();
  e.map = map;
  e.keyframes = r.keyframes;
  e.seconds = seconds;
  e.detail = (r.free_keyframes < r.keyframes ? std::to_string(r.free_keyframes) + " of them free (a region), " : "") +
             std::to_string(r.points) + " points (" + std::to_string(r.points_low_parallax) +
                 (options_.optimization.global_ba_low_parallax_inverse_depth ? " as inverse depths" : " held") +
                 " for their parallax), " + std::to_string(r.iterations) + " iterations (" + std::to_string(r.rejected_steps) + " steps rejected), rmse " +
             std::to_string(r.initial_rmse_px) + " -> " + std::to_string(r.final_rmse_px) + " px (" +
             std::to_string(r.final_inliers) + " of " + std::to_string(r.observations - r.observations_dropped) +
             " observations inliers: " + std::to_string(r.final_inlier_rmse_px) + " px), " +
             std::to_string(r.keyframes_added_meanwhile) + " keyframes added meanwhile";
  AddEvent(e);
}

void ServerBackend::RunRedundancyStep() {
  const auto removed = redundancy_.Step([this](KeyframeId id) { matcher_.OnKeyframeErased(id); });
  if (removed.empty()) return;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.keyframes_removed += static_cast<int64_t>(removed.size());
}

void ServerBackend::Stop() { scheduler_.Stop(); }

void ServerBackend::Resume() { scheduler_.Resume(); }

void ServerBackend::ProcessAllQueued() {
  for (;;) {
    bool worked = false;
    for (const AgentId a : scheduler_.Agents()) {
      while (RunHandlerOnce(a, std::chrono::milliseconds(0)) == HandlerStep::kProcessed) worked = true;
    }
    while (RunPlaceRecognitionOnce(std::chrono::milliseconds(0))) worked = true;
    while (RunOptimization(std::chrono::milliseconds(0), /*respect_pause=*/false)) worked = true;
    if (!worked || scheduler_.stopping()) return;
  }
}

void ServerBackend::WaitUntilIdle() { scheduler_.WaitUntilIdle(); }

AgentAcks ServerBackend::TakeAcks(AgentId agent) {
  std::lock_guard<std::mutex> lock(acks_mutex_);
  AgentAcks out;
  std::swap(out, acks_[agent]);
  return out;
}

std::optional<ServerMapData> ServerBackend::Neighbourhood(AgentId agent, KeyframeId reference_kf,
                                                          const std::unordered_set<KeyframeId>* held) const {
  NeighbourhoodOptions o;
  o.keyframes = options_.neighbourhood_k;
  o.own_keyframes_after_s = options_.share_own_keyframes_after_s;
  return AgentNeighbourhood(*stack_, agent, reference_kf, o, held);
}

BackendStatus ServerBackend::Status() const {
  BackendStatus s;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    s.stats = stats_;
  }
  s.stats.place = matcher_.stats();
  s.queues = scheduler_.Depths();
  s.agents = scheduler_.Agents();
  s.stats.agent_slots_released = scheduler_.slots_released();
  s.idle = scheduler_.Idle();
  return s;
}

MapStackSnapshot ServerBackend::Snapshot() const {
  MapStackSnapshot s = MapStackSnapshot::Of(*stack_);
  std::lock_guard<std::mutex> lock(stats_mutex_);
  s.events = events_;
  return s;
}

void ServerBackend::AddEvent(ServerEvent e) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  events_.push_back(std::move(e));
}

}  // namespace ccm
