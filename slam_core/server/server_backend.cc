#include "slam_core/server/server_backend.h"

#include <algorithm>

#include "slam_core/server/map_persistence.h"
#include "slam_core/server/outgoing.h"

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

const char* ServerEventKindName(ServerEvent::Kind kind) {
  switch (kind) {
    case ServerEvent::Kind::kNewMap: return "new_map";
    case ServerEvent::Kind::kFusion: return "fusion";
    case ServerEvent::Kind::kLoop: return "loop";
    case ServerEvent::Kind::kGlobalBa: return "global_ba";
  }
  return "?";
}

ServerBackend::ServerBackend(std::shared_ptr<const Vocabulary> vocabulary, ServerOptions options)
    : vocabulary_(std::move(vocabulary)),
      options_(std::move(options)),
      start_(Clock::now()),
      stack_(options_.map),
      mapper_(options_.mapping),
      matcher_(vocabulary_, options_.place, &stack_),
      redundancy_(options_.redundancy.theta, options_.redundancy.seed) {}

ServerBackend::~ServerBackend() { Stop(); }

double ServerBackend::Elapsed() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

void ServerBackend::SetNewAgentCallback(std::function<void(AgentId)> callback) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
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
  bool is_new = false;
  std::function<void(AgentId)> callback;
  // queue_mutex_ and stats_mutex_ are both leaves: a refusal is decided under the first and
  // counted under the second, never both held.
  enum class Refused { kNo, kAgent, kQueueFull, kQueueBytes, kSegments } refused = Refused::kNo;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    is_new = !queues_.count(agent);
    if (agent == kServerAgent || (is_new && static_cast<int>(queues_.size()) >= options_.max_agents)) {
      refused = Refused::kAgent;
    } else {
      AgentQueue& q = queues_[agent];
      if (is_new) q.registration = std::make_unique<AgentRegistration>(agent, &stack_, options_.registration);
      // Registration opens a map for the segment of every item, not only the batch's.
      std::set<uint64_t> fresh;
      for (const uint64_t s : SegmentsOf(batch)) {
        if (!q.segments.count(s)) fresh.insert(s);
      }
      const size_t bytes = ApproxBatchBytes(batch);
      if (static_cast<int>(q.batches.size()) >= options_.max_queued_batches_per_agent) {
        refused = Refused::kQueueFull;
      } else if (!q.batches.empty() && q.bytes + bytes > options_.max_queued_bytes_per_agent) {
        refused = Refused::kQueueBytes;
      } else if (static_cast<int>(q.segments.size() + fresh.size()) > options_.max_segments_per_agent) {
        refused = Refused::kSegments;
      } else {
        q.segments.insert(fresh.begin(), fresh.end());
        if (!batch.empty()) {
          q.batches.push_back(std::move(batch));
          q.bytes += bytes;
        }
        callback = is_new ? on_new_agent_ : nullptr;
      }
    }
  }
  if (refused != Refused::kNo) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    if (refused == Refused::kAgent) {
      ++stats_.batches_rejected;
    } else if (refused == Refused::kSegments) {
      AgentCounters& c = stats_.agents[agent];
      ++c.segments_refused;
      c.last_rejection = "more than max_segments_per_agent (" + std::to_string(options_.max_segments_per_agent) +
                         ") map segments";
    } else {
      AgentCounters& c = stats_.agents[agent];
      ++c.batches_dropped;
      if (refused == Refused::kQueueBytes) {
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
  queue_cv_.notify_all();
  if (callback) callback(agent);
  return rejected;
}

bool ServerBackend::RunHandlerOnce(AgentId agent, std::chrono::milliseconds timeout) {
  AgentBatch batch;
  AgentRegistration* reg = nullptr;
  {
    std::unique_lock<std::mutex> lock(queue_mutex_);
    auto ready = [&] {
      const auto it = queues_.find(agent);
      return stopping_ || (it != queues_.end() && !it->second.batches.empty() && !it->second.busy);
    };
    if (!queue_cv_.wait_for(lock, timeout, ready) || stopping_) return false;
    AgentQueue& q = queues_.at(agent);
    batch = std::move(q.batches.front());
    q.batches.pop_front();
    q.bytes -= ApproxBatchBytes(batch);
    q.busy = true;
    reg = q.registration.get();
  }
  ProcessBatch(reg, batch);
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    queues_.at(agent).busy = false;
  }
  queue_cv_.notify_all();
  NotifyIdleChange();
  return true;
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
  for (const RegisteredKeyframe& r : report.keyframes) {
    const auto t1 = Clock::now();
    SharedMapLock locked = LockMapOf(stack_, r.id);
    if (!locked.map) continue;
    const auto kf = locked.map->map().keyframe(r.id);
    if (!kf) continue;
    const ServerMappingReport m = mapper_.Process(locked.map.get(), kf);
    fusion_ms += m.fusion_ms;
    local_ba_ms += m.local_ba_ms;
    local_bas += m.local_ba;
    if (m.skipped) {
      ++skipped;
    } else {
      for_place_recognition.push_back(r.id);
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
    std::lock_guard<std::mutex> lock(acks_mutex_);
    AgentAcks& a = acks_[reg->agent()];
    a.keyframes.insert(a.keyframes.end(), report.acked_keyframes.begin(), report.acked_keyframes.end());
    a.map_points.insert(a.map_points.end(), report.acked_points.begin(), report.acked_points.end());
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    AgentCounters& c = stats_.agents[reg->agent()];
    ++c.batches;
    c.keyframes_registered += static_cast<int64_t>(report.keyframes.size());
    c.keyframes_duplicate += skipped;
    c.keyframes_anchor_only += report.anchors_registered + report.anchors_dropped;
    c.keyframes_kept_on_track += report.kept_on_track;
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
  if (!for_place_recognition.empty()) {
    {
      std::lock_guard<std::mutex> lock(pr_mutex_);
      pr_queue_.insert(pr_queue_.end(), for_place_recognition.begin(), for_place_recognition.end());
    }
    pr_cv_.notify_all();
  }
  if (options_.redundancy.enabled && !report.keyframes.empty()) {
    {
      std::lock_guard<std::mutex> lock(opt_mutex_);
      redundancy_budget_ += static_cast<int64_t>(report.keyframes.size());
    }
    opt_cv_.notify_all();
  }
}

bool ServerBackend::RunPlaceRecognitionOnce(std::chrono::milliseconds timeout) {
  KeyframeId kf;
  {
    std::unique_lock<std::mutex> lock(pr_mutex_);
    if (!pr_cv_.wait_for(lock, timeout, [&] { return stopping_ || !pr_queue_.empty(); }) || stopping_) return false;
    kf = pr_queue_.front();
    pr_queue_.pop_front();
    pr_busy_ = true;
  }
  if (const auto detection = matcher_.Process(kf)) HandleDetection(*detection);
  {
    std::lock_guard<std::mutex> lock(pr_mutex_);
    pr_busy_ = false;
  }
  NotifyIdleChange();
  return true;
}

void ServerBackend::HandleDetection(const PlaceDetection& d) {
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    // A running global BA of an involved map is about to be stale: let it stop now.
    if (ba_running_.valid() && (ba_running_ == d.query_map || ba_running_ == d.candidate_map)) abort_ba_ = true;
  }
  ServerEvent e;
  e.time_s = Elapsed();
  e.agent = d.query.agent();
  e.query = d.query;
  e.candidate = d.candidate;
  e.query_from_candidate = d.query_from_candidate;
  if (const auto m = stack_.MapHolding(d.query)) {
    if (const auto kf = m->map().keyframe(d.query)) e.stamp_ns = kf->stamp_ns();
  }
  if (d.kind == PlaceDetection::Kind::kLoop) {
    const LoopReport r = CloseLoop(&stack_, d, options_);
    if (!r.closed) return;
    matcher_.OnLoopClosed(r.map);
    e.kind = ServerEvent::Kind::kLoop;
    e.map = r.map;
    e.seconds = r.seconds;
    e.detail = "moved " + std::to_string(r.correction_m) + " m / " + std::to_string(r.correction_deg) +
               " deg, scale x" + std::to_string(r.scale_correction) + ", " + std::to_string(r.points_fused) +
               " points fused, " + std::to_string(r.loop_connections) + " loop connections";
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.loops;
    }
    if (options_.optimization.global_ba_after_loop) RequestGlobalBa(r.map);
  } else {
    const FusionReport r =
        FuseMaps(&stack_, d, [this](MapId absorbed, MapId kept) { matcher_.OnMapsFused(absorbed, kept); });
    if (!r.fused) return;
    e.kind = ServerEvent::Kind::kFusion;
    e.map = r.kept;
    e.other_map = r.absorbed;
    e.seconds = r.seconds;
    e.detail = "scale " + std::to_string(r.kept_from_absorbed.scale()) + ", " + std::to_string(r.keyframes_moved) +
               " keyframes moved, " + std::to_string(r.points_merged) + " points merged, overlap " +
               (r.refined ? "refined on " : "not refined, ") + std::to_string(r.overlap_inliers) + "/" +
               std::to_string(r.overlap_pairs) + " point pairs";
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.fusions;
    }
    {
      std::lock_guard<std::mutex> lock(opt_mutex_);
      ba_pending_.erase(r.absorbed);
    }
    if (options_.optimization.global_ba_after_fusion) RequestGlobalBa(r.kept);
  }
  if (const auto m = stack_.GetMap(e.map)) e.keyframes = static_cast<int>(m->map().num_keyframes());
  AddEvent(e);
}

void ServerBackend::ScheduleGlobalBa(MapId map) { RequestGlobalBa(map); }

void ServerBackend::RequestGlobalBa(MapId map) {
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    ba_pending_.insert(map);
  }
  opt_cv_.notify_all();
}

bool ServerBackend::RunOptimizationOnce(std::chrono::milliseconds timeout) { return RunOptimization(timeout, true); }

bool ServerBackend::RunOptimization(std::chrono::milliseconds timeout, bool respect_pause) {
  MapId map;
  {
    std::unique_lock<std::mutex> lock(opt_mutex_);
    // A global BA may start once its map's pause since the last one is over (duty cycle).
    auto next_ba = [&]() -> std::optional<std::pair<MapId, Clock::time_point>> {
      std::optional<std::pair<MapId, Clock::time_point>> best;
      for (const MapId m : ba_pending_) {
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
      if (Clock::now() >= deadline) return false;
      opt_cv_.wait_until(lock, until);
    }
    if (stopping_) return false;
    opt_busy_ = true;
    const auto n = next_ba();
    if (n && n->second <= Clock::now()) {
      map = n->first;
      ba_pending_.erase(map);
      ba_running_ = map;
      abort_ba_ = false;
    } else {
      --redundancy_budget_;
    }
  }
  if (map.valid()) {
    GlobalBaReport r;
    if (const auto smap = stack_.GetMap(map)) {
      GlobalBaOptions o;
      o.iterations = options_.optimization.global_ba_iterations;
      o.threads = options_.optimization.global_ba_threads;
      r = RunGlobalBundleAdjustment(smap, o, &abort_ba_);
    }
    const bool again = (r.outcome == GlobalBaReport::Outcome::kAborted || r.outcome == GlobalBaReport::Outcome::kStale) &&
                       stack_.GetMap(map) != nullptr && !stopping_;
    {
      std::lock_guard<std::mutex> lock(opt_mutex_);
      ba_running_ = MapId();
      if (again) ba_pending_.insert(map);
      if (r.outcome == GlobalBaReport::Outcome::kApplied) {
        const double s = r.snapshot_s + r.solve_s + r.write_back_s;
        ba_not_before_[map] = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                 std::chrono::duration<double>(options_.optimization.global_ba_pause_factor * s));
      }
    }
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      if (r.outcome == GlobalBaReport::Outcome::kApplied) {
        ++stats_.global_ba_applied;
        stats_.global_ba_seconds.emplace_back(r.keyframes, r.snapshot_s + r.solve_s + r.write_back_s);
      }
      stats_.global_ba_aborted += r.outcome == GlobalBaReport::Outcome::kAborted;
      stats_.global_ba_stale += r.outcome == GlobalBaReport::Outcome::kStale;
    }
    if (r.outcome == GlobalBaReport::Outcome::kApplied) {
      ServerEvent e;
      e.kind = ServerEvent::Kind::kGlobalBa;
      e.time_s = Elapsed();
      e.map = map;
      e.keyframes = r.keyframes;
      e.seconds = r.snapshot_s + r.solve_s + r.write_back_s;
      e.detail = std::to_string(r.points) + " points, " + std::to_string(r.iterations) + " iterations, rmse " +
                 std::to_string(r.initial_rmse_px) + " -> " + std::to_string(r.final_rmse_px) + " px, " +
                 std::to_string(r.keyframes_added_meanwhile) + " keyframes added meanwhile";
      AddEvent(e);
    }
  } else {
    RunRedundancyStep();
  }
  {
    std::lock_guard<std::mutex> lock(opt_mutex_);
    opt_busy_ = false;
  }
  opt_cv_.notify_all();
  NotifyIdleChange();
  return true;
}

bool ServerBackend::RunRedundancyStep() {
  // Round-robin over the maps large enough to thin out.
  auto maps = stack_.Maps();
  maps.erase(std::remove_if(maps.begin(), maps.end(),
                            [&](const auto& m) {
                              return static_cast<int>(m->map().num_keyframes()) < options_.redundancy.min_map_keyframes;
                            }),
             maps.end());
  if (maps.empty()) return false;
  const auto smap = maps[redundancy_next_++ % maps.size()];
  std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  if (smap->retired()) return false;
  std::vector<KeyframeId> protect;
  for (const AgentHandler& h : stack_.HandlersOfMap(smap->id())) protect.push_back(h.last_keyframe);
  const RedundancyStep step = redundancy_.Step(smap.get(), protect);
  for (const KeyframeId id : step.removed) matcher_.OnKeyframeErased(id);
  if (!step.removed.empty()) {
    std::lock_guard<std::mutex> slock(stats_mutex_);
    stats_.keyframes_removed += static_cast<int64_t>(step.removed.size());
  }
  return !step.removed.empty();
}

void ServerBackend::Stop() {
  stopping_ = true;
  abort_ba_ = true;
  {
    std::lock_guard<std::mutex> a(queue_mutex_);
  }
  {
    std::lock_guard<std::mutex> b(pr_mutex_);
  }
  {
    std::lock_guard<std::mutex> c(opt_mutex_);
  }
  queue_cv_.notify_all();
  pr_cv_.notify_all();
  opt_cv_.notify_all();
  NotifyIdleChange();
}

void ServerBackend::Resume() {
  stopping_ = false;
  abort_ba_ = false;
}

void ServerBackend::ProcessAllQueued() {
  for (;;) {
    bool worked = false;
    for (const AgentId a : agents()) {
      while (RunHandlerOnce(a, std::chrono::milliseconds(0))) worked = true;
    }
    while (RunPlaceRecognitionOnce(std::chrono::milliseconds(0))) worked = true;
    while (RunOptimization(std::chrono::milliseconds(0), /*respect_pause=*/false)) worked = true;
    if (!worked || stopping_) return;
  }
}

bool ServerBackend::Idle() const {
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

void ServerBackend::NotifyIdleChange() {
  { std::lock_guard<std::mutex> lock(idle_mutex_); }
  idle_cv_.notify_all();
}

void ServerBackend::WaitUntilIdle() {
  std::unique_lock<std::mutex> lock(idle_mutex_);
  idle_cv_.wait(lock, [this] { return stopping_ || Idle(); });
}

AgentAcks ServerBackend::TakeAcks(AgentId agent) {
  std::lock_guard<std::mutex> lock(acks_mutex_);
  AgentAcks out;
  std::swap(out, acks_[agent]);
  return out;
}

std::optional<ServerMapData> ServerBackend::Neighbourhood(AgentId agent, KeyframeId reference_kf) const {
  NeighbourhoodOptions o;
  o.keyframes = options_.neighbourhood_k;
  return AgentNeighbourhood(stack_, agent, reference_kf, o);
}

BackendStats ServerBackend::stats() const {
  BackendStats s;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    s = stats_;
  }
  s.place = matcher_.stats();
  return s;
}

QueueDepths ServerBackend::queue_depths() const {
  QueueDepths d;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    for (const auto& [a, q] : queues_) {
      d.agent_batches[a] = q.batches.size() + (q.busy ? 1 : 0);
      d.agent_bytes[a] = q.bytes;
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

std::vector<ServerEvent> ServerBackend::events() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return events_;
}

void ServerBackend::AddEvent(ServerEvent e) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  events_.push_back(std::move(e));
}

std::vector<AgentId> ServerBackend::agents() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  std::vector<AgentId> out;
  for (const auto& [a, q] : queues_) out.push_back(a);
  return out;
}

std::vector<MapSummary> ServerBackend::Maps() const {
  std::vector<MapSummary> out;
  for (const auto& m : stack_.Maps()) {
    MapSummary s;
    s.id = m->id();
    s.keyframes = m->map().num_keyframes();
    s.map_points = m->map().num_map_points();
    s.anchored = m->anchors().size();
    for (const AgentHandler& h : stack_.HandlersOfMap(m->id())) s.agents.insert(h.agent);
    out.push_back(s);
  }
  return out;
}

bool ServerBackend::Save(const std::string& path, std::string* error) const {
  return MapPersistence::Save(stack_, events(), path, error);
}

std::unique_ptr<ServerBackend> ServerBackend::Load(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                                                   ServerOptions options, std::string* error, std::string* warning) {
  auto contents = MapPersistence::Load(path, options.map, error, warning);
  if (!contents) return nullptr;
  auto backend = std::make_unique<ServerBackend>(std::move(vocabulary), std::move(options));
  backend->Restore(std::move(*contents));
  return backend;
}

void ServerBackend::Restore(MapStackContents contents) {
  for (auto& m : contents.maps) stack_.RestoreMap(std::move(m));
  for (const AgentHandler& h : contents.handlers) stack_.RestoreHandler(h);
  stack_.set_next_map_counter(contents.next_map_counter);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    events_ = std::move(contents.events);
  }
  for (const auto& m : stack_.Maps()) {
    std::shared_lock<WriterPreferringMutex> lock(m->structure_mutex());
    for (const auto& kf : m->map().keyframes()) matcher_.AddToDatabase(*kf, m->id());
  }
}

std::vector<ServerKeyframePose> ServerBackend::AgentTrajectory(AgentId agent) const {
  std::vector<ServerKeyframePose> out;
  for (const auto& m : stack_.Maps()) {
    std::shared_lock<WriterPreferringMutex> lock(m->structure_mutex());
    for (const auto& [id, info] : m->infos()) {
      const auto kf = id.agent() == agent ? m->map().keyframe(id) : nullptr;
      if (kf) out.push_back({id, m->id(), info.segment, kf->stamp_ns(), kf->world_from_cam(), true});
    }
    for (const auto& [id, anchor] : m->anchors()) {
      if (id.agent() != agent) continue;
      if (const auto pose = m->PoseOf(id)) out.push_back({id, m->id(), anchor.segment, anchor.stamp_ns, *pose, false});
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
  return out;
}

}  // namespace ccm
