#include "tools/replay/replay_session.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <unordered_set>

#include "server_runtime/backend_runner.h"
#include "slam_core/vo/agent_vo.h"
#include "slam_core/vo/change_packer.h"

namespace ccm::replay {
namespace {

using Clock = std::chrono::steady_clock;

// The server's acknowledgements as the agent's bounded local map sees them.
class AckSet final : public AckSource {
 public:
  bool IsAcked(KeyframeId kf) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return acked_.count(kf) > 0;
  }
  void Add(const std::vector<KeyframeId>& kfs) {
    std::lock_guard<std::mutex> lock(mutex_);
    acked_.insert(kfs.begin(), kfs.end());
  }

 private:
  mutable std::mutex mutex_;
  std::unordered_set<KeyframeId> acked_;
};

struct Agent {
  ReplayAgentInput input;
  std::shared_ptr<const CameraModel> camera;
  AckSet acks;
  std::unique_ptr<AgentVo> vo;
  std::unique_ptr<ChangePacker> packer;
  std::optional<Frame> next;
  int64_t last_send_ns = -1;
  int64_t first_ns = -1;
  std::vector<AgentBatch> held;  // packed during a link cut, delivered when it ends
  std::vector<AgentBatch> late;  // the burst's points, when they come after its keyframes
  std::unordered_set<MapPointId> late_ids;  // the points in `late`
  int64_t late_at_ns = 0;
  int64_t frames = 0, tracked = 0;
  Trajectory gt;
};

class Session {
 public:
  Session(const ReplayOptions& o, ServerBackend* backend, const ProgressFn& progress)
      : o_(o), backend_(backend), progress_(progress) {}

  bool Open(std::vector<ReplayAgentInput> inputs, std::string* error) {
    for (auto& in : inputs) {
      auto a = std::make_unique<Agent>();
      a->camera.reset(MakeCamera(in.source->intrinsics()).release());
      if (!a->camera) {
        *error = in.name + ": invalid camera calibration: " + ValidateIntrinsics(in.source->intrinsics());
        return false;
      }
      a->vo = std::make_unique<AgentVo>(in.id, a->camera, o_.vo, &a->acks, /*synchronous_mapping=*/!o_.threaded,
                                          o_.agent_vocabulary);
      ChangePackerOptions packing;
      packing.new_keyframe_delay_s = o_.new_keyframe_delay_s;
      packing.anchor_duplicates = o_.anchor_duplicates;
      a->packer = std::make_unique<ChangePacker>(in.id, packing);
      const int64_t n = in.source->size();
      total_ += o_.max_frames >= 0 && (n < 0 || n > o_.max_frames) ? o_.max_frames : std::max<int64_t>(n, 0);
      a->input = std::move(in);
      agents_.push_back(std::move(a));
    }
    return true;
  }

  void RunDeterministic() {
    for (auto& a : agents_) Advance(a.get());
    for (;;) {
      Agent* a = nullptr;
      for (auto& c : agents_) {
        if (c->next && (!a || c->next->stamp_ns < a->next->stamp_ns)) a = c.get();
      }
      if (!a) break;
      Track(a, *a->next);
      Advance(a);
      MaybeProgress();
    }
    for (auto& a : agents_) {
      a->packer->FlushNext();  // the end of the flights: whatever the send delay still holds
      Exchange(a.get(), a->last_send_ns + 1, /*last=*/true);
    }
    backend_->ProcessAllQueued();
    if (o_.final_global_ba) {
      backend_->ScheduleFinish();
      backend_->ProcessAllQueued();
    }
  }

  void RunThreaded() {
    server::BackendRunner runner(backend_);
    std::vector<std::thread> threads;
    for (auto& a : agents_) {
      threads.emplace_back([this, agent = a.get()] { RunAgentThread(agent); });
    }
    {
      std::unique_lock<std::mutex> lock(done_mutex_);
      while (finished_ < agents_.size()) {
        done_cv_.wait_for(lock, std::chrono::duration<double>(o_.progress_period_s));
        lock.unlock();
        MaybeProgress();
        lock.lock();
      }
    }
    for (auto& t : threads) t.join();
    backend_->WaitUntilIdle();
    if (o_.final_global_ba) {
      backend_->ScheduleFinish();
      backend_->WaitUntilIdle();
    }
    runner.Stop();
  }

  void Collect(RunResult* r) {
    const MapStackSnapshot maps = backend_->Snapshot();
    for (auto& a : agents_) {
      AgentRunResult ar;
      ar.name = a->input.name;
      ar.id = a->input.id;
      ar.frames = a->frames;
      ar.frames_tracked = a->tracked;
      const AgentVoStats s = a->vo->stats();
      ar.keyframes_created = s.keyframes_created;
      ar.segments = s.segments;
      ar.relocalizations = s.relocalizations;
      ar.tracking_ms = s.tracking_ms;
      ar.ground_truth = a->gt;
      for (const KeyframePose& p : a->vo->KeyframeTrajectory()) {
        // The local map also holds keyframes the server shared from other agents.
        if (p.id.agent() != a->input.id) continue;
        ar.vo_keyframes.push_back({p.stamp_ns, p.world_from_cam});
        ar.vo_segments[p.segment].push_back({p.stamp_ns, p.world_from_cam});
      }
      const auto by_stamp = [](const auto& x, const auto& y) { return x.stamp_ns < y.stamp_ns; };
      std::sort(ar.vo_keyframes.begin(), ar.vo_keyframes.end(), by_stamp);
      for (auto& [segment, t] : ar.vo_segments) std::sort(t.begin(), t.end(), by_stamp);
      ar.server_keyframes = maps.AgentTrajectory(a->input.id);
      ar.revisit_links = maps.AgentRevisitLinks(a->input.id, report::kRevisitLinkGapNs, report::kRevisitLinkMinPoints);
      if (!a->input.source->error().empty() && r->error.empty()) r->error = a->input.name + ": " + a->input.source->error();
      r->agents.push_back(std::move(ar));
    }
  }

 private:
  void Advance(Agent* a) {
    a->next.reset();
    if (o_.max_frames >= 0 && a->frames >= o_.max_frames) return;
    a->next = a->input.source->Next();
  }

  void Track(Agent* a, const Frame& f) {
    if (f.world_from_cam_gt) a->gt.push_back({f.stamp_ns, *f.world_from_cam_gt});
    const TrackingResult r = a->vo->TrackFrame(f);
    ++a->frames;
    a->tracked += r.world_from_cam.has_value();
    ++frames_done_;
    if (o_.threaded && r.new_keyframe) a->vo->WaitUntilMappingIdle();
    if (a->last_send_ns < 0) a->last_send_ns = a->first_ns = f.stamp_ns;
    if (f.stamp_ns - a->last_send_ns >= static_cast<int64_t>(o_.send_period_s * 1e9)) Exchange(a, f.stamp_ns);
  }

  // One communication round: changes to the server, acks and the neighbourhood back.
  // The last round of a flight (`last`) always reaches the server: the agent drains its link.
  void Exchange(Agent* a, int64_t stamp_ns, bool last = false) {
    a->last_send_ns = stamp_ns;
    AgentBatch batch = a->packer->Pack(a->vo->TakeChanges(), stamp_ns);
    const KeyframeId ref = batch.reference_kf;
    if (!last && InLinkCut(*a, stamp_ns)) {
      if (!batch.empty()) a->held.push_back(std::move(batch));
      return;  // no acks, no map sharing: the agent flies on its own
    }
    if (!a->late.empty() && (last || stamp_ns >= a->late_at_ns)) {
      for (AgentBatch& b : a->late) Submit(std::move(b));
      a->late.clear();
      a->late_ids.clear();
    }
    for (AgentBatch& b : a->held) {
      if (o_.link_cut_points_late_s > 0.0 && !last) SplitOffPoints(&b, a, stamp_ns);
      Submit(std::move(b));
    }
    a->held.clear();
    if (!batch.empty()) Submit(std::move(batch));
    if (!o_.threaded) backend_->ProcessAllQueued();
    a->acks.Add(backend_->TakeAcks(a->input.id).keyframes);
    if (o_.map_sharing && ref.valid()) {
      if (auto data = backend_->Neighbourhood(a->input.id, ref)) a->vo->ApplyServerData(std::move(*data));
    }
  }

  // The points of a burst's batch leave for later; its keyframes that link one of them are
  // flagged as the live reassembly flags keyframes released without their points.
  void SplitOffPoints(AgentBatch* b, Agent* a, int64_t stamp_ns) const {
    AgentBatch points;
    points.agent = b->agent;
    points.segment = b->segment;
    points.reference_kf = b->reference_kf;
    points.stamp_ns = b->stamp_ns;
    std::swap(points.map_points, b->map_points);
    std::swap(points.map_point_updates, b->map_point_updates);
    for (const MapPointData& mp : points.map_points) a->late_ids.insert(mp.id);
    for (KeyframeData& kf : b->keyframes) {
      for (const auto& link : kf.point_links) kf.points_incomplete |= a->late_ids.count(link.second) > 0;
    }
    if (!points.empty()) a->late.push_back(std::move(points));
    a->late_at_ns = stamp_ns + static_cast<int64_t>(o_.link_cut_points_late_s * 1e9);
  }

  bool InLinkCut(const Agent& a, int64_t stamp_ns) const {
    if (o_.link_cut_at_s < 0.0 || a.first_ns < 0) return false;
    const double t = (stamp_ns - a.first_ns) * 1e-9;
    return t >= o_.link_cut_at_s && t < o_.link_cut_at_s + o_.link_cut_s;
  }

  void Submit(AgentBatch batch) {
    if (o_.on_batch) {
      std::lock_guard<std::mutex> lock(batch_mutex_);
      o_.on_batch(batch);
    }
    backend_->Submit(std::move(batch));
  }

  void RunAgentThread(Agent* a) {
    std::atomic<bool> mapping_run{true};
    std::thread mapping([&] {
      while (mapping_run) a->vo->RunMappingOnce(std::chrono::milliseconds(200));
    });
    for (Advance(a); a->next; Advance(a)) Track(a, *a->next);
    a->vo->WaitUntilMappingIdle();
    mapping_run = false;
    a->vo->Stop();
    mapping.join();
    a->vo->DrainMapping();
    a->packer->FlushNext();  // the end of the flight: whatever the send delay still holds
    Exchange(a, a->last_send_ns + 1, /*last=*/true);
    {
      std::lock_guard<std::mutex> lock(done_mutex_);
      ++finished_;
    }
    done_cv_.notify_all();
  }

  void MaybeProgress() {
    if (!progress_) return;
    const auto now = Clock::now();
    std::lock_guard<std::mutex> lock(progress_mutex_);
    if (std::chrono::duration<double>(now - last_progress_).count() < o_.progress_period_s) return;
    last_progress_ = now;
    ReplayProgress p;
    p.elapsed_s = std::chrono::duration<double>(now - start_).count();
    p.frames_done = frames_done_;
    p.frames_total = total_;
    p.maps = backend_->Snapshot().Summaries();
    const BackendStats s = backend_->Status().stats;
    p.fusions = s.fusions;
    p.loops = s.loops;
    progress_(p);
  }

  const ReplayOptions& o_;
  ServerBackend* backend_;
  const ProgressFn& progress_;
  std::vector<std::unique_ptr<Agent>> agents_;
  std::atomic<int64_t> frames_done_{0};
  int64_t total_ = 0;
  const Clock::time_point start_ = Clock::now();
  std::mutex progress_mutex_;
  Clock::time_point last_progress_ = Clock::now();
  std::mutex batch_mutex_;  // serializes on_batch across agent threads
  std::mutex done_mutex_;
  std::condition_variable done_cv_;
  size_t finished_ = 0;
};

}  // namespace

std::string ReplayOptions::Validate() const {
  if (auto e = vo.Validate(); !e.empty()) return "vo: " + e;
  if (auto e = server.Validate(); !e.empty()) return "server: " + e;
  if (!(send_period_s > 0.0)) return "send period must be > 0";
  if (!(new_keyframe_delay_s >= 0.0)) return "keyframe delay must be >= 0";
  if (const std::string e = anchor_duplicates.Validate(); !e.empty()) return "anchor duplicates: " + e;
  if (!(progress_period_s > 0.0)) return "progress period must be > 0";
  if (link_cut_at_s >= 0.0 && !(link_cut_s > 0.0)) return "a link cut needs a length > 0 s";
  if (!(link_cut_points_late_s >= 0.0)) return "late points need a delay >= 0 s";
  return "";
}

RunResult RunReplay(std::vector<ReplayAgentInput> agents, const ReplayOptions& options, ServerBackend* backend,
                       const ProgressFn& progress) {
  RunResult result;
  const auto t0 = Clock::now();
  if (const std::string e = options.Validate(); !e.empty()) {
    result.error = e;
    return result;
  }
  std::unordered_set<AgentId> ids;
  for (const auto& a : agents) {
    if (!a.source) result.error = a.name + ": no frame source";
    if (a.id == kServerAgent || !ids.insert(a.id).second) result.error = a.name + ": agent ids must be unique and >= 1";
  }
  if (!result.error.empty()) return result;
  Session session(options, backend, progress);
  if (!session.Open(std::move(agents), &result.error)) return result;
  if (options.threaded) {
    session.RunThreaded();
  } else {
    session.RunDeterministic();
  }
  session.Collect(&result);
  const MapStackSnapshot maps = backend->Snapshot();
  result.events = maps.events;
  result.maps = maps.Summaries();
  result.stats = backend->Status().stats;
  result.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return result;
}

}  // namespace ccm::replay
