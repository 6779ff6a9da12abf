#include "agent_runtime/agent_runner.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>

#include "slam_core/eval/metrics.h"
#include "slam_core/io/calibration_yaml.h"
#include "slam_core/io/dataset.h"
#include "slam_core/io/video_source.h"
#include "slam_core/io/trajectory_io.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "agent_runtime/agent_comm.h"
#include "agent_runtime/agent_metrics.h"
#include "agent_runtime/cpu_usage.h"
#include "agent_runtime/live_camera_source.h"
#include "agent_runtime/ros2_camera_source.h"
#include "runtime_common/process_memory.h"
#include "slam_core/common/install_paths.h"
#include "slam_core/vo/agent_vo.h"
#ifdef CCM_AGENT_WITH_SIM
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"
#endif

#ifndef CCM_DEFAULT_VOCABULARY
#define CCM_DEFAULT_VOCABULARY ""
#endif

namespace ccm::agent {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

namespace {

// --calibration FILE for the inputs that carry none (a camera; ROS 2 images instead of CameraInfo).
bool ReadCalibration(const std::string& path, CameraIntrinsics* intrinsics, std::string* error) {
  const IoStatus status = ReadCalibrationYaml(path, intrinsics);
  if (!status.ok()) *error = status.message();
  return status.ok();
}

}  // namespace

std::unique_ptr<FrameSource> OpenFrameSource(const RunOptions& o, const volatile bool* stop, std::string* error) {
  if (!o.ros2_image.empty()) {
    Ros2CameraOptions r;
    r.image_topic = o.ros2_image;
    r.camera_info_topic = o.ros2_camera_info;
    r.domain_id = o.ros2_domain >= 0 ? o.ros2_domain : DefaultRos2Domain();
    r.qos_file = o.qos_file;
    r.queue = static_cast<size_t>(o.ros2_queue);
    r.end_after_s = o.end_after_s;
    r.info_wait_s = o.ros2_info_wait_s;
    r.stop = stop;
    if (!o.calibration.empty()) {
      CameraIntrinsics intrinsics;
      if (!ReadCalibration(o.calibration, &intrinsics, error)) return nullptr;
      r.calibration = intrinsics;
    }
    return Ros2CameraSource::Create(r, error);
  }
  if (!o.sim_scenario.empty()) {
#ifndef CCM_AGENT_WITH_SIM
    *error = "this ccm_agent was built without the simulator (CCM_AGENT_ONLY): use --dataset or --video";
    return nullptr;
#else
    const auto scenario = sim::LoadScenario(o.sim_scenario, error);
    if (!scenario) return nullptr;
    std::shared_ptr<const sim::Simulation> simulation(sim::Simulation::Create(*scenario, error));
    if (!simulation) return nullptr;
    if (o.sim_agent < 0 || o.sim_agent >= simulation->num_agents()) {
      *error = "scenario '" + o.sim_scenario + "' has " + std::to_string(simulation->num_agents()) +
               " agents; --sim-agent " + std::to_string(o.sim_agent) + " does not exist";
      return nullptr;
    }
    return std::make_unique<sim::SimFrameSource>(simulation, o.sim_agent);
#endif
  }
  if (!o.video.empty()) {
    CameraIntrinsics intrinsics;
    if (!ReadCalibration(o.calibration, &intrinsics, error)) return nullptr;
    // A camera or a GStreamer pipeline: live (its own capture thread, skips, stalls, reopen).
    if (!std::filesystem::is_regular_file(o.video)) {
      if (!IsGStreamerPipeline(o.video) && !IsCameraIndex(o.video) && !std::filesystem::exists(o.video)) {
        *error = o.video + ": cannot open camera or video (no such file or device)";
        return nullptr;
      }
      LiveCameraOptions live;
      live.name = o.video;
      live.end_after_s = o.end_after_s;
      live.stop = stop;
      return LiveCameraSource::Create(MakeOpenCvGrabber(o.video), intrinsics, live, error);
    }
    IoStatus status;
    auto video = VideoSource::Open(o.video, intrinsics, &status);
    if (!video) *error = status.message();
    return video;
  }
  DatasetOptions d;
  d.path = o.dataset;
  d.calibration_path = o.calibration;
  const auto format = ParseDatasetFormat(o.format);
  d.format = *format;
  IoStatus status;
  auto source = OpenDataset(d, &status);
  if (!source) *error = status.message();
  return source;
}

namespace {

bool WriteTum(const std::string& path, const std::vector<KeyframePose>& poses, std::string* error) {
  Trajectory t;
  for (const auto& p : poses) t.push_back({p.stamp_ns, p.world_from_cam});
  std::sort(t.begin(), t.end(), [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
  const IoStatus s = WriteTumTrajectory(path, t);
  if (!s.ok()) *error = s.message();
  return s.ok();
}

// Sleeps so that frames are consumed at their recorded rate times `speed`.
class Pacer {
 public:
  explicit Pacer(double speed) : speed_(speed) {}
  void Wait(int64_t stamp_ns) {
    if (speed_ <= 0) return;
    if (!started_) {
      started_ = true;
      first_ns_ = stamp_ns;
      start_ = Clock::now();
      return;
    }
    std::this_thread::sleep_until(Due(stamp_ns));
  }
  /// For --skip-late-frames: true when the frame after this one is already due, so a camera
  /// that holds only its newest frame would have replaced this one. Call for every frame
  /// read, before Wait; the first frame is never late, and unpaced input never is.
  bool Late(int64_t stamp_ns) {
    const int64_t period_ns = last_ns_ >= 0 ? stamp_ns - last_ns_ : 0;
    last_ns_ = stamp_ns;
    return speed_ > 0 && started_ && Clock::now() >= Due(stamp_ns + period_ns);
  }

 private:
  Clock::time_point Due(int64_t stamp_ns) const {
    const double media_s = (stamp_ns - first_ns_) * 1e-9 / speed_;
    return start_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(media_s));
  }
  double speed_;
  bool started_ = false;
  int64_t first_ns_ = 0, last_ns_ = -1;
  Clock::time_point start_;
};

std::string InputName(const RunOptions& o) {
  if (!o.sim_scenario.empty()) return "sim:" + o.sim_scenario;
  if (!o.ros2_image.empty()) return "ROS 2 " + o.ros2_image;
  return !o.video.empty() ? o.video : o.dataset;
}

int Error(const std::string& message, int code) {
  std::cerr << "error: " << message << "\n";
  return code;
}

// The relocalization vocabulary: --vocab, else the installed one beside the binary, else the
// build tree's; none (brute-force relocalization) with --vocab none or when none is built in.
bool LoadAgentVocabulary(const RunOptions& o, std::shared_ptr<const Vocabulary>* vocabulary, std::string* error) {
  const std::string path =
      o.vocabulary.empty() ? rt::FindDataFile(rt::kInstalledVocabulary, CCM_DEFAULT_VOCABULARY) : o.vocabulary;
  if (path.empty()) {
    spdlog::info("no vocabulary built in: relocalization matches against every local map point (give --vocab FILE)");
    return true;
  }
  if (o.vocabulary == "none") return true;
  auto loaded = LoadVocabularyFile(path, error);
  if (!loaded) {
    *error = "vocabulary: " + *error + " (give --vocab FILE, or --vocab none for brute-force relocalization)";
    return false;
  }
  *vocabulary = std::make_shared<const Vocabulary>(std::move(*loaded));
  spdlog::info("relocalization vocabulary {} ({} words)", path, (*vocabulary)->num_words());
  return true;
}

// What the tracking loop leaves behind.
struct Flight {
  int64_t frames = 0, tracked = 0;
  int64_t skipped = 0;       ///< frames skipped while tracking was busy (a live source's + skipped_late)
  int64_t skipped_late = 0;  ///< --skip-late-frames: paced frames whose successor was already due
  double tracking_cpu_s = 0.0;  ///< the tracking thread inside TrackFrame
  double input_cpu_s = 0.0;     ///< the same thread reading / decoding / rendering frames and pacing
  double setup_cpu_s = 0.0;     ///< the whole process before the first frame (vocabulary, input, DDS)
  std::vector<KeyframePose> ground_truth;  ///< per frame, where the source has it and it is written
  Clock::time_point start;
};

void LogProgress(const Flight& f, const FrameSource& source, const TrackingResult& last, const AgentVo& vo,
                 const AgentComm* comm) {
  const double el = std::chrono::duration<double>(Clock::now() - f.start).count();
  const auto m = vo.map();
  std::string link;
  if (comm) {
    const AgentCommStats c = comm->Stats();
    link = fmt::format(" | KFs sent {} acked {} resent {} unacked {} | server msgs {} (+{} KFs)", c.kfs_sent,
                       c.kfs_acked, c.kfs_resent, c.kfs_unacked, c.server_msgs, c.server_keyframes_received);
  }
  spdlog::info("frames {}/{} ({:.1f} fps) state {} tracked {:.1f}% KFs in map {}{}", f.frames, source.size(),
               f.frames / el, TrackingStateName(last.state), 100.0 * f.tracked / f.frames,
               m ? m->num_keyframes() : 0, link);
}

// The tracking thread's loop (this thread): every frame of the source through the VO, at
// the requested pace, until the end, --max-frames or *stop.
Flight Fly(const RunOptions& o, FrameSource* source, AgentVo* vo, AgentComm* comm, FlightGauges* gauges,
           const volatile bool* stop) {
  // A live camera is neither paced nor made to wait: it skips what the tracker cannot take.
  Pacer pacer(source->live() || o.rate == "max" ? 0.0 : o.rate == "realtime" ? 1.0 : std::stod(o.rate));
  Flight f;
  f.start = Clock::now();
  f.setup_cpu_s = ProcessCpuSeconds();
  const double cpu_start = ThreadCpuSeconds();
  auto last_progress = f.start;
  TrackingResult last;
  bool road_hint_given = false;
  while (!*stop && (o.max_frames < 0 || f.frames + f.skipped_late < o.max_frames)) {  // frames read
    auto frame = source->Next();
    if (!frame) break;
    if (o.skip_late_frames && pacer.Late(frame->stamp_ns)) {
      gauges->frames_skipped = source->frames_skipped() + ++f.skipped_late;
      continue;
    }
    pacer.Wait(frame->stamp_ns);
    // Kept only when it is written: per frame it grew the agent's memory by 7 MB per hour.
    if (frame->world_from_cam_gt && !o.ground_truth_out.empty()) {
      f.ground_truth.push_back({KeyframeId(), MapId(), frame->stamp_ns, *frame->world_from_cam_gt});
    }
    const double cpu_before = ThreadCpuSeconds();
    last = vo->TrackFrame(*frame);
    f.tracking_cpu_s += ThreadCpuSeconds() - cpu_before;
    if (comm) comm->SetTrackingState(static_cast<int>(last.state));
    // Offline at full speed: let mapping finish each keyframe, as it would keep up in real
    // time; otherwise tracking races ahead on a map that lags behind (seen on KITTI).
    if (o.rate == "max" && !source->live() && last.new_keyframe) vo->WaitUntilMappingIdle();
    ++f.frames;
    f.tracked += last.world_from_cam.has_value();
    gauges->frames = f.frames;
    gauges->tracked = f.tracked;
    gauges->frames_skipped = source->frames_skipped() + f.skipped_late;
    gauges->state = static_cast<int>(last.state);
    gauges->keyframes_created += last.new_keyframe ? 1 : 0;
    gauges->segments += last.new_segment ? 1 : 0;
    if (last.new_segment) {
      spdlog::warn("frame {}: relocalization kept failing, continuing on a new map segment", f.frames - 1);
    }
    // One default does not fit a road ahead: its matches are mostly distant or on a plane,
    // and the default initializer waits for parallax that never comes. Say so once.
    if (!road_hint_given && last.state == TrackingState::kInitializing &&
        vo->stats().road_like_init_attempts >= kRoadProfileHintAttempts) {
      road_hint_given = true;
      spdlog::warn("still initializing after {} frames: most matches are distant or on a plane (a road ahead?); "
                   "for road vehicles use deploy/config/agent-road.yaml (vo: init_count_distant_points, "
                   "init_features 4000)", f.frames);
    }
    if (Clock::now() - last_progress > std::chrono::duration<double>(o.progress_period_s)) {
      LogProgress(f, *source, last, *vo, comm);
      last_progress = Clock::now();
    }
  }
  f.input_cpu_s = ThreadCpuSeconds() - cpu_start - f.tracking_cpu_s;
  f.skipped = source->frames_skipped() + f.skipped_late;
  if (f.skipped > 0) {
    spdlog::warn("frames came faster than tracking took them: {} frames skipped ({:.1f}% of {})", f.skipped,
                 100.0 * f.skipped / static_cast<double>(f.skipped + f.frames), f.skipped + f.frames);
  }
  return f;
}

// --trajectory-out, --ground-truth-out, --keyframes-out (the agent's own keyframes, not the
// server's shared ones).
bool WriteOutputs(const RunOptions& o, const AgentVo& vo, const Flight& f, std::string* error) {
  if (!o.trajectory_out.empty() && !WriteTum(o.trajectory_out, vo.FrameTrajectory(), error)) return false;
  if (!o.ground_truth_out.empty() && !WriteTum(o.ground_truth_out, f.ground_truth, error)) return false;
  std::vector<KeyframePose> own_keyframes;
  for (const KeyframePose& p : vo.KeyframeTrajectory()) {
    if (p.id.agent() == o.agent_id) own_keyframes.push_back(p);
  }
  return o.keyframes_out.empty() || WriteTum(o.keyframes_out, own_keyframes, error);
}


// CPU per frame by thread and peak RSS (issue 29's budget). "setup" is the process before
// the first frame (loading the vocabulary, opening the input, joining DDS), spread over the
// frames so that the parts add up to "total": a one-off, which a long flight makes small.
// "other" is the rest: Fast DDS's threads and the final drain. The mapping thread's time
// covers the local BA run on it; the tracking thread's own mapping (if any) is in "tracking".
nlohmann::json Footprint(const Flight& f, double mapping_cpu_s, const AgentComm* comm) {
  const double process_s = ProcessCpuSeconds();
  const double comm_s = comm ? comm->cpu_seconds() : 0.0;
  const double other_s =
      std::max(0.0, process_s - f.setup_cpu_s - f.tracking_cpu_s - f.input_cpu_s - mapping_cpu_s - comm_s);
  const double per_frame = f.frames ? 1000.0 / static_cast<double>(f.frames) : 0.0;
  const nlohmann::json footprint = {{"cpu_ms_per_frame",
                                     {{"tracking", f.tracking_cpu_s * per_frame},
                                      {"mapping", mapping_cpu_s * per_frame},
                                      {"comm", comm_s * per_frame},
                                      {"input", f.input_cpu_s * per_frame},
                                      {"setup", f.setup_cpu_s * per_frame},
                                      {"other", other_s * per_frame},
                                      {"total", process_s * per_frame}}},
                                    {"peak_rss_mb", rt::PeakRssMb()}};
  const nlohmann::json& ms = footprint["cpu_ms_per_frame"];
  spdlog::info("CPU ms/frame: tracking {:.1f}, mapping {:.1f}, comm {:.1f}, input {:.1f}, other {:.1f}, total {:.1f} "
               "(set-up {:.0f} ms before the first frame); peak RSS {:.0f} MB",
               ms["tracking"].get<double>(), ms["mapping"].get<double>(), ms["comm"].get<double>(),
               ms["input"].get<double>(), ms["other"].get<double>(), ms["total"].get<double>(),
               1000.0 * f.setup_cpu_s,
               footprint["peak_rss_mb"].get<double>());
  return footprint;
}

// The summary line printed on stdout at the end (and its log lines).
nlohmann::json Summary(const RunOptions& o, const Flight& f, const AgentVoStats& s, const AgentComm* comm) {
  const double wall_s = std::chrono::duration<double>(Clock::now() - f.start).count();
  spdlog::info("done: {} frames in {:.1f} s, tracked {:.1f}%, {} keyframes ({} culled, {} lost), {} segments", f.frames,
               wall_s, f.frames ? 100.0 * f.tracked / f.frames : 0.0, s.keyframes_created, s.mapping.keyframes_culled,
               s.trim.removed_lost, s.segments);
  spdlog::info("tracking ms/frame: median {:.1f} p95 {:.1f}; local mapping ms/keyframe: median {:.1f} p95 {:.1f}",
               Percentile(s.tracking_ms, 0.5), Percentile(s.tracking_ms, 0.95), Percentile(s.mapping_ms, 0.5),
               Percentile(s.mapping_ms, 0.95));
  nlohmann::json summary = {{"agent_id", o.agent_id},
                            {"frames", f.frames},
                            {"frames_skipped", f.skipped},
                            {"tracked", f.tracked},
                            {"keyframes_created", s.keyframes_created},
                            {"keyframes_in_map", s.keyframes_in_map},
                            {"keyframes_culled", s.mapping.keyframes_culled},
                            {"map_points_in_map", s.map_points_in_map},
                            {"keyframes_lost", s.trim.removed_lost},
                            {"keyframes_dropped_unpersisted", s.trim.removed_unpersisted},
                            {"segments", s.segments},
                            {"relocalizations", s.relocalizations},
                            {"weak_poses", s.weak_poses},
                            {"server_keyframes_added", s.server.keyframes_added},
                            {"server_keyframes_updated", s.server.keyframes_updated},
                            {"server_points_added", s.server.points_added},
                            {"server_points_updated", s.server.points_updated},
                            {"server_keyframes_not_held", s.server.keyframes_not_held},
                            {"server_points_not_held", s.server.points_not_held},
                            {"tracking_ms_median", Percentile(s.tracking_ms, 0.5)},
                            {"tracking_ms_p95", Percentile(s.tracking_ms, 0.95)},
                            {"mapping_ms_median", Percentile(s.mapping_ms, 0.5)},
                            {"mapping_ms_p95", Percentile(s.mapping_ms, 0.95)},
                            {"wall_s", wall_s}};
  nlohmann::json reasons = nlohmann::json::object();
  for (size_t k = 1; k < s.keyframe_reasons.size(); ++k) {
    reasons[KeyframeReasonName(static_cast<KeyframeReason>(k))] = s.keyframe_reasons[k];
  }
  summary["keyframe_reasons"] = reasons;
  if (comm) {
    summary["link"] = LinkSummaryJson(*comm);
    for (const auto& t : comm->Traffic()) summary["traffic"][t.topic + ":" + t.direction] = t.payload_bytes;
  }
  return summary;
}

}  // namespace

std::string RunOptions::Validate() const {
  if (dataset.empty() + sim_scenario.empty() + video.empty() + ros2_image.empty() != 3) {
    return "give exactly one of --dataset DIR, --sim SCENARIO, --video DEVICE|FILE or --ros2-image TOPIC";
  }
  if (ros2_image.empty() && !ros2_camera_info.empty()) return "--ros2-camera-info needs --ros2-image";
  if (ros2_queue < 1 || ros2_queue > 1000) return "--ros2-queue must be in 1..1000";
  if (!(end_after_s >= 0)) return "--end-after must be >= 0 (0: wait for ever)";
  if (ros2_domain < -1 || ros2_domain > 232) return "--ros2-domain must be in 0..232";
  if (!video.empty() && calibration.empty()) return "--video needs --calibration FILE.yaml";
  if (!ParseDatasetFormat(format)) return "--format must be auto, euroc, tum or kitti, got '" + format + "'";
  if (rate != "max" && rate != "realtime") {
    try {
      if (std::stod(rate) <= 0) return "--rate factor must be > 0";
    } catch (...) {
      return "--rate must be max, realtime or a speed factor (e.g. 0.5), got '" + rate + "'";
    }
  }
  if (agent_id < 1 || agent_id > 65535) return "agent id must be in 1..65535";
  if (!(drain_s >= 0.0)) return "--drain must be >= 0";
  if (metrics_port < -1 || metrics_port > 65535) return "--metrics port must be in 0..65535";
  if (metrics_port >= 0 && metrics_bind.empty()) return "--metrics-bind must name an address";
  return vo.Validate();
}

int RunAgent(const RunOptions& o, const AgentConfig* comm_config, const rt::SessionOptions* session,
             const volatile bool* stop) {
  if (const std::string problem = o.Validate(); !problem.empty()) return Error(problem, 2);
  std::string error;
  auto source = OpenFrameSource(o, stop, &error);
  if (!source) return Error(error, 2);
  std::shared_ptr<const CameraModel> camera(MakeCamera(source->intrinsics()));
  if (!camera) return Error("invalid camera calibration: " + ValidateIntrinsics(source->intrinsics()), 2);
  // Connected: the server's acknowledgements decide when keyframes may leave the local map.
  // Standalone: every keyframe may leave once older than N; --no-acks keeps them buffered as
  // for an unreachable server (up to N+B, then lost).
  AckAll ack_all;
  AckNone ack_none;
  AckTracker tracker(std::chrono::milliseconds(comm_config ? static_cast<int>(comm_config->resend_holdoff_s * 1000) : 1000));
  const AckSource& acks = comm_config ? static_cast<const AckSource&>(tracker)
                          : o.no_acks ? static_cast<const AckSource&>(ack_none)
                                      : static_cast<const AckSource&>(ack_all);
  std::shared_ptr<const Vocabulary> vocabulary;
  if (!LoadAgentVocabulary(o, &vocabulary, &error)) return Error(error, 2);
  AgentVo vo(static_cast<AgentId>(o.agent_id), camera, o.vo, &acks, /*synchronous_mapping=*/false, vocabulary);
  std::unique_ptr<VoDataSource> vo_source;  // declared before comm: destroyed after it
  std::unique_ptr<AgentComm> comm;
  if (comm_config) {
    vo_source = std::make_unique<VoDataSource>(&vo, static_cast<AgentId>(o.agent_id), comm_config->Packing());
    comm = AgentComm::Create(*comm_config, *session, vo_source.get(), &tracker, &error);
    if (!comm) return Error(error, 1);
    comm->Start();
  }
  spdlog::info("{} VO on {} ({} frames, {}x{} {})", comm ? "agent " + std::to_string(o.agent_id) : std::string("standalone"),
               InputName(o), source->size(),
               camera->width(), camera->height(), CameraTypeName(camera->type()));
  // --metrics: started after the comm module it reads, stopped before it.
  FlightGauges gauges;
  std::unique_ptr<MetricsEndpoint> metrics;
  if (o.metrics_port >= 0) {
    const AgentComm* link = comm.get();
    metrics = MetricsEndpoint::Start(o.metrics_bind, o.metrics_port, [&gauges, link, id = o.agent_id] {
      const AgentCommStats stats = link ? link->Stats() : AgentCommStats{};
      return AgentMetricsText(id, gauges, link ? &stats : nullptr);
    }, &error);
    if (!metrics) return Error(error, 2);
    spdlog::info("metrics on http://{}:{}/metrics", o.metrics_bind, metrics->port());
  }
  // The local-mapping thread: started and joined here.
  std::atomic<bool> mapping_run{true};
  double mapping_cpu_s = 0.0;  // written by the mapping thread before it ends, read after join
  std::thread mapping([&] {
    while (mapping_run) vo.RunMappingOnce(std::chrono::milliseconds(100));
    mapping_cpu_s = ThreadCpuSeconds();
  });
  const Flight flight = Fly(o, source.get(), &vo, comm.get(), &gauges, stop);
  vo.WaitUntilMappingIdle();
  mapping_run = false;
  vo.Stop();
  mapping.join();
  vo.DrainMapping();
  bool drained = true;
  if (comm) {
    // The last keyframes still need the server's acknowledgement (resends included).
    drained = comm->WaitDrained(std::chrono::milliseconds(static_cast<int64_t>(o.drain_s * 1000)));
    if (metrics) metrics->Stop();
    comm->Stop();
    if (!drained) spdlog::warn("{} keyframes still unacknowledged after {:.0f} s", comm->Stats().kfs_unacked, o.drain_s);
  }
  if (!source->error().empty()) return Error(source->error(), 1);
  if (!WriteOutputs(o, vo, flight, &error)) return Error(error, 1);
  nlohmann::json summary = Summary(o, flight, vo.stats(), comm.get());
  summary["footprint"] = Footprint(flight, mapping_cpu_s, comm.get());
  if (const auto* ros2 = dynamic_cast<const Ros2CameraSource*>(source.get())) {
    const Ros2CameraSource::Counters c = ros2->counters();
    summary["ros2_camera"] = {{"delivered", c.delivered}, {"skipped", c.skipped}, {"lost", c.lost},
                              {"out_of_order", c.out_of_order}, {"stalls", c.stalls}};
  }
  if (const auto* camera = dynamic_cast<const LiveCameraSource*>(source.get())) {
    const LiveCameraSource::Counters c = camera->counters();
    summary["camera"] = {{"delivered", c.delivered}, {"skipped", c.skipped}, {"stalls", c.stalls},
                         {"disappearances", c.disappearances}, {"reopened", c.reopened}};
  }
  std::cout << summary.dump() << std::endl;
  return drained ? 0 : 3;
}

}  // namespace ccm::agent
