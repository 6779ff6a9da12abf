#include "slam_core/vo/agent_vo.h"

#include <algorithm>
#include <unordered_map>

namespace ccm {
namespace {

OrbExtractorOptions WithFeatures(OrbExtractorOptions o, int n) {
  o.num_features = n;
  return o;
}

// Appends until the cap, then overwrites cyclically (sample n goes to n % cap).
void AddSample(std::vector<double>* samples, int64_t n, double value) {
  if (samples->size() < AgentVoStats::kMaxTimingSamples) {
    samples->push_back(value);
  } else {
    (*samples)[static_cast<size_t>(n) % AgentVoStats::kMaxTimingSamples] = value;
  }
}

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

AgentVo::AgentVo(AgentId agent, std::shared_ptr<const CameraModel> camera, VoOptions options,
                 const AckSource* acks, bool synchronous_mapping, std::shared_ptr<const Vocabulary> vocabulary)
    : shared_(agent, std::move(camera), options),
      synchronous_(synchronous_mapping),
      extractor_(options.orb),
      init_extractor_(WithFeatures(options.orb, options.init_num_features)),
      tracker_(&shared_, [this](KeyframeJob job) { Enqueue(MappingJob{std::move(job), nullptr, std::nullopt}); },
               [this] { return mapping_idle(); }),
      mapper_(&shared_, acks) {
  if (vocabulary) shared_.relocalization = std::make_unique<RelocalizationIndex>(std::move(vocabulary));
}

TrackingResult AgentVo::TrackFrame(const Frame& frame) {
  const auto t0 = std::chrono::steady_clock::now();
  const bool initializing = !tracker_.map();
  OrbExtractor& extractor = initializing ? init_extractor_ : extractor_;
  VoFrame f = MakeVoFrame(frame.stamp_ns, frame_index_++, extractor.Extract(frame.image), *shared_.camera);
  const TrackingResult r = tracker_.Track(std::move(f));
  const double ms = MsSince(t0);
  {
    std::lock_guard<std::mutex> lock(map_mutex_);
    current_map_ = tracker_.map();
    current_ref_ = tracker_.reference_kf();
  }
  if (r.world_from_cam && shared_.options.record_frame_trajectory) {
    if (const auto& ref = tracker_.reference_keyframe()) {
      frame_records_.push_back({frame.stamp_ns, ref->id(), ref->cam_from_world() * *r.world_from_cam, *r.world_from_cam});
    }
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.frames;
    stats_.frames_tracked += r.world_from_cam.has_value();
    stats_.keyframes_created += r.new_keyframe;
    stats_.keyframe_reasons = tracker_.keyframe_reasons();
    stats_.segments = tracker_.segments_started() + 1;
    stats_.road_like_init_attempts = tracker_.road_like_init_attempts();
    stats_.relocalizations = tracker_.relocalizations();
    stats_.weak_poses = tracker_.weak_poses();
    AddSample(&stats_.tracking_ms, stats_.frames - 1, ms);
  }
  // Nobody may be taking changes (standalone, server unreachable): keep the log bounded.
  if (frame_index_ % 16 == 0 && shared_.changes.size() > shared_.options.max_pending_changes) {
    if (const auto m = CurrentMap()) shared_.changes.Prune(*m);
  }
  if (synchronous_) DrainMapping();
  return r;
}

void AgentVo::Enqueue(MappingJob job) {
  {
    std::lock_guard<std::mutex> lock(jobs_mutex_);
    jobs_.push_back(std::move(job));
  }
  jobs_cv_.notify_one();
}

void AgentVo::ApplyServerData(ServerMapData data) {
  auto map = CurrentMap();
  if (!map) return;  // nothing to attach it to while initializing
  Enqueue(MappingJob{std::nullopt, std::move(map), std::move(data)});
}

bool AgentVo::RunMappingOnce(std::chrono::milliseconds timeout) {
  MappingJob job;
  {
    std::unique_lock<std::mutex> lock(jobs_mutex_);
    if (!jobs_cv_.wait_for(lock, timeout, [this] { return stopping_ || !jobs_.empty(); })) return false;
    if (jobs_.empty()) return false;
    job = std::move(jobs_.front());
    jobs_.pop_front();
    mapping_busy_ = true;
  }
  ProcessJob(job);
  {
    std::lock_guard<std::mutex> lock(jobs_mutex_);
    mapping_busy_ = false;
  }
  idle_cv_.notify_all();
  return true;
}

void AgentVo::DrainMapping() {
  while (RunMappingOnce(std::chrono::milliseconds(0))) {
  }
}

void AgentVo::Stop() {
  {
    std::lock_guard<std::mutex> lock(jobs_mutex_);
    stopping_ = true;
  }
  jobs_cv_.notify_all();
  idle_cv_.notify_all();
}

void AgentVo::WaitUntilMappingIdle() {
  std::unique_lock<std::mutex> lock(jobs_mutex_);
  idle_cv_.wait(lock, [this] { return stopping_ || (jobs_.empty() && !mapping_busy_); });
}

bool AgentVo::mapping_idle() const {
  std::lock_guard<std::mutex> lock(jobs_mutex_);
  return jobs_.empty() && !mapping_busy_;
}

void AgentVo::ProcessJob(const MappingJob& job) {
  const auto t0 = std::chrono::steady_clock::now();
  if (job.server) {
    std::lock_guard<std::mutex> lock(mapper_mutex_);
    if (job.map == CurrentMap()) {
      mapper_.ApplyServerData(job.map.get(), *job.server);
      SyncRelocalizationIndex();
    }
    PublishMapperStats(&*job.server);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mapper_mutex_);
    mapper_.Process(*job.keyframe);
    PublishMapperStats();
  }
  SyncRelocalizationIndex();
  const double ms = MsSince(t0);
  std::lock_guard<std::mutex> lock(stats_mutex_);
  AddSample(&stats_.mapping_ms, mapping_samples_++, ms);
}

void AgentVo::PublishMapperStats(const ServerMapData* applied) {
  // Every job may have trimmed server keyframes (the local map bound) or added some.
  std::vector<KeyframeId> held;
  if (const auto m = CurrentMap()) {
    for (const auto& kf : m->keyframes()) {
      if (kf->from_server()) held.push_back(kf->id());
    }
  }
  // Copied after each job so that stats() (the comm thread's heartbeat, progress lines)
  // never waits behind a local BA on mapper_mutex_. Lock order mapper_mutex_ -> stats_mutex_.
  std::lock_guard<std::mutex> lock(stats_mutex_);
  holdings_.keyframes = std::move(held);
  // Also when the data was for a replaced segment: it was consumed, and what it carried is
  // not held (the server then sends it in full again).
  if (applied) holdings_.applied_stamp_ns = std::max(holdings_.applied_stamp_ns, applied->stamp_ns);
  stats_.mapping = mapper_.stats();
  stats_.trim = mapper_.trim_stats();
  stats_.server = mapper_.server_stats();
}

ServerHoldings AgentVo::Holdings() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return holdings_;
}

void AgentVo::SyncRelocalizationIndex() {
  if (!shared_.relocalization) return;
  if (const auto m = CurrentMap()) shared_.relocalization->Sync(*m);
}

VoChanges AgentVo::TakeChanges() {
  VoChanges c;
  {
    std::lock_guard<std::mutex> lock(map_mutex_);
    c.map = current_map_;
    c.reference_kf = current_ref_;
  }
  shared_.changes.Take(&c.keyframes, &c.map_points);
  return c;
}

std::shared_ptr<Map> AgentVo::map() const { return CurrentMap(); }

std::shared_ptr<Map> AgentVo::CurrentMap() const {
  std::lock_guard<std::mutex> lock(map_mutex_);
  return current_map_;
}

AgentVoStats AgentVo::stats() const {
  AgentVoStats s;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    s = stats_;  // the mapper's part as of its last job (PublishMapperStats)
  }
  if (shared_.relocalization) s.relocalization_index_size = shared_.relocalization->size();
  if (const auto m = CurrentMap()) {
    s.keyframes_in_map = m->num_keyframes();
    s.map_points_in_map = m->num_map_points();
  }
  return s;
}

std::vector<KeyframePose> AgentVo::FrameTrajectory() const {
  std::unordered_map<KeyframeId, SE3> kf_poses;
  for (const KeyframePose& k : KeyframeTrajectory()) kf_poses.emplace(k.id, k.world_from_cam);
  std::vector<KeyframePose> out;
  out.reserve(frame_records_.size());
  for (const FrameRecord& r : frame_records_) {
    const auto it = kf_poses.find(r.reference);
    const SE3 pose = it != kf_poses.end() ? it->second * r.reference_from_cam : r.world_from_cam;
    out.push_back({r.reference, MapId(), r.stamp_ns, pose});
  }
  return out;
}

std::vector<KeyframePose> AgentVo::KeyframeTrajectory() const {
  std::vector<KeyframePose> out;
  {
    std::lock_guard<std::mutex> lock(mapper_mutex_);
    for (const auto& [id, sp] : mapper_.retired_keyframes()) out.push_back({id, MapId(), sp.first, sp.second});
  }
  if (const auto m = CurrentMap()) {
    for (const auto& kf : m->keyframes()) out.push_back({kf->id(), m->id(), kf->stamp_ns(), kf->world_from_cam()});
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

}  // namespace ccm
