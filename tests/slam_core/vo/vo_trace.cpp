// vo_trace: one simulated agent through the VO, one line per frame, to find where and why
// tracking degrades: state, pose-optimization inliers, keyframes, segment, the error of the
// motion over the last second against ground truth (rotation, and translation direction
// since monocular scale is unknown), each frame's own rotation error (total and yaw) and
// sideways step error, how far the mapping step turned the newest keyframe, and the map's
// scale over the last second (docs/vo.md "Seed 13's agent 1"). Not a test; a diagnosis tool.
//   vo_trace --scenario gen:3 --agent 0 [--from 50 --to 120] [--set kf_turn_fov_share=0.2]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>

#include "slam_core/place_recognition/vocabulary_io.h"
#include "tests/slam_core/vo/vo_sim_run.h"

namespace {

struct Sample {
  int64_t index;
  ccm::SE3 gt, est;
};

double AngleDeg(const Eigen::Quaterniond& q) { return Eigen::AngleAxisd(q).angle() * 180.0 / M_PI; }

// A tracked frame's errors against ground truth; -1 (0 for the signed ones) where unknown.
struct FrameErrors {
  double rot_1s = -1, dir_1s = -1;        // motion over the last second [deg]
  double step = -1, step_yaw = 0;         // this frame against the one before [deg]
  double step_gt_yaw = 0;                 // the true yaw of that step [deg]
  double step_sideways_m = 0;             // its sideways error [m of the ground truth]
  double scale = 0;                       // ground-truth m per map unit over the last second
};

// `window` holds the tracked frames of the last second, this one last.
FrameErrors MeasureFrame(const std::deque<Sample>& window) {
  FrameErrors e;
  const Sample& now = window.back();
  std::optional<ccm::SE3> step_gt, step_est;
  if (window.size() >= 2 && window[window.size() - 2].index == now.index - 1) {
    const Sample& prev = window[window.size() - 2];
    step_gt = prev.gt.inverse() * now.gt;
    step_est = prev.est.inverse() * now.est;
    const Eigen::Quaterniond err = step_gt->rotation().conjugate() * step_est->rotation();
    e.step = AngleDeg(err);
    const Eigen::AngleAxisd ea(err), ga(step_gt->rotation());
    e.step_yaw = ea.angle() * ea.axis().y() * 180.0 / M_PI;  // camera y: the yaw of a level camera
    e.step_gt_yaw = ga.angle() * ga.axis().y() * 180.0 / M_PI;
  }
  const Sample& old = window.front();
  if (old.index == now.index) return e;
  const ccm::SE3 d_gt = old.gt.inverse() * now.gt, d_est = old.est.inverse() * now.est;
  e.rot_1s = AngleDeg(d_gt.rotation().conjugate() * d_est.rotation());
  if (d_gt.translation().norm() > 0.05 && d_est.translation().norm() > 1e-9) {
    e.dir_1s = std::acos(std::clamp(d_gt.translation().normalized().dot(d_est.translation().normalized()), -1.0, 1.0)) *
               180.0 / M_PI;
    e.scale = d_gt.translation().norm() / d_est.translation().norm();
    // A yaw traded for a sideways step shows as step_sideways_m ~ -step_yaw * depth.
    if (step_gt) e.step_sideways_m = (e.scale * step_est->translation() - step_gt->translation()).x();
  }
  return e;
}

constexpr const char* kSettableKeys =
    "min_triangulation_parallax_deg, kf_urgent_ratio, kf_inlier_drop_ratio, kf_min_interval_s, kf_turn_fov_share, "
    "kf_coverage_ratio, triangulation_neighbours, min_baseline_depth_ratio";

// One "key=value" of kSettableKeys into options; an error message or "".
std::string SetVoOption(const std::string& kv, ccm::VoOptions* o) {
  const size_t eq = kv.find('=');
  if (eq == std::string::npos) return "--set needs KEY=VALUE, got '" + kv + "'";
  const std::string key = kv.substr(0, eq);
  char* end = nullptr;
  const double v = std::strtod(kv.c_str() + eq + 1, &end);
  if (end == kv.c_str() + eq + 1 || *end != '\0') return "--set " + key + ": not a number";
  if (key == "min_triangulation_parallax_deg") o->min_triangulation_parallax_deg = v;
  else if (key == "kf_urgent_ratio") o->keyframe.urgent_ratio = v;
  else if (key == "kf_inlier_drop_ratio") o->keyframe.inlier_drop_ratio = v;
  else if (key == "kf_min_interval_s") o->keyframe.min_interval_s = v;
  else if (key == "kf_turn_fov_share") o->keyframe.turn_fov_share = v;
  else if (key == "kf_coverage_ratio") o->keyframe.coverage_ratio = v;
  else if (key == "min_baseline_depth_ratio") o->min_baseline_depth_ratio = v;
  else if (key == "triangulation_neighbours") o->triangulation_neighbours = static_cast<int>(v);
  else return "--set: unknown key '" + key + "' (known: " + kSettableKeys + ")";
  return o->Validate();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"vo_trace: per-frame VO diagnosis on a simulated agent"};
  std::string scenario = "hall3", vocab_path = CCM_DEFAULT_VOCABULARY;
  int agent = 0;
  int64_t from = 0, to = -1, stride = 1;
  app.add_option("--scenario", scenario, "built-in, gen:SEED[:MAX_AGENTS] (bench_fusion --max-agents) or YAML")->capture_default_str();
  app.add_option("--agent", agent, "agent index")->capture_default_str();
  app.add_option("--from", from, "first frame to print")->capture_default_str();
  app.add_option("--to", to, "last frame to run (-1: all)")->capture_default_str();
  app.add_option("--stride", stride, "every n-th frame (2: 10 Hz of a 20 Hz flight)")->capture_default_str();
  app.add_option("--vocab", vocab_path, "relocalization vocabulary ('none': brute force)")->capture_default_str();
  std::vector<std::string> overrides;
  app.add_option("--set", overrides, "VO option KEY=VALUE (repeatable): " + std::string(kSettableKeys));
  CLI11_PARSE(app, argc, argv);
  std::string error;
  const auto sim = ccm::testing::LoadSimulation(scenario, &error);
  if (!sim) {
    std::fprintf(stderr, "vo_trace: %s\n", error.c_str());
    return 2;
  }
  std::shared_ptr<const ccm::Vocabulary> vocab;
  if (vocab_path != "none") {
    auto v = ccm::LoadVocabularyFile(vocab_path, &error);
    if (!v) {
      std::fprintf(stderr, "vo_trace: %s\n", error.c_str());
      return 2;
    }
    vocab = std::make_shared<const ccm::Vocabulary>(std::move(*v));
  }
  ccm::sim::SimFrameSource source(sim, agent, 0, stride, to >= 0 ? to + 1 : -1);
  std::shared_ptr<const ccm::CameraModel> camera(ccm::MakeCamera(source.intrinsics()));
  ccm::AckAll acks;  // standalone, as ccm_agent --standalone
  ccm::VoOptions vopt;
  for (const std::string& kv : overrides) {
    if (auto e = SetVoOption(kv, &vopt); !e.empty()) {
      std::fprintf(stderr, "vo_trace: %s\n", e.c_str());
      return 2;
    }
  }
  ccm::AgentVo vo(static_cast<ccm::AgentId>(agent + 1), camera, vopt, &acks, true, vocab);
  const double rate = sim->scenario().agents.at(agent).rate_hz / static_cast<double>(stride);
  std::deque<Sample> window;  // tracked frames of the last second
  std::printf("frame    t_s state        inl kf seg  speed  yawrate | 1 s motion: rot err deg  dir err deg | step rot err deg  map turn deg  step yaw: true, error  sideways step error m  1 s scale m/unit\n");
  int64_t index = 0;
  // The newest own keyframe and its pose as of the last frame: how far the mapping step that
  // ran since (a local BA after a keyframe) turned it, i.e. the map under the tracker.
  std::optional<ccm::KeyframePose> watched;
  while (auto frame = source.Next()) {
    const ccm::TrackingResult r = vo.TrackFrame(*frame);
    // The newest own keyframe before this frame: how far the mapping step since turned it.
    double kf_turn = -1;
    std::optional<ccm::KeyframePose> newest;
    for (const ccm::KeyframePose& k : vo.KeyframeTrajectory()) {
      if (watched && k.id == watched->id) kf_turn = AngleDeg(watched->world_from_cam.rotation().conjugate() * k.world_from_cam.rotation());
      if (k.id.agent() == static_cast<ccm::AgentId>(agent + 1) && (!newest || k.stamp_ns > newest->stamp_ns)) newest = k;
    }
    watched = newest;
    FrameErrors e;
    if (r.world_from_cam) {
      window.push_back({index, *frame->world_from_cam_gt, *r.world_from_cam});
      while (window.front().index < index - static_cast<int64_t>(rate)) window.pop_front();
      e = MeasureFrame(window);
    } else {
      window.clear();
    }
    const double t = index / rate;
    const ccm::sim::Trajectory& traj = sim->trajectory(agent);
    const double speed = traj.Velocity(t).norm();
    const ccm::SE3 a = traj.WorldFromCam(std::max(0.0, t - 0.05)), b = traj.WorldFromCam(t + 0.05);
    const double yaw_rate = AngleDeg(a.rotation().conjugate() * b.rotation()) / 0.1;
    if (index >= from) {
      std::printf("%5lld %6.2f %-12s %4d %2s %3llu %6.2f %8.1f | %8.2f %12.2f | %6.2f %6.2f %6.2f %6.2f %7.3f %8.3f\n",
                  static_cast<long long>(index), t,
                  ccm::TrackingStateName(r.state), r.inliers, r.new_keyframe ? "KF" : "",
                  static_cast<unsigned long long>(r.segment.counter()), speed, yaw_rate, e.rot_1s, e.dir_1s, e.step, kf_turn,
                  e.step_gt_yaw, e.step_yaw, e.step_sideways_m, e.scale);
    }
    ++index;
  }
  const auto s = vo.stats();
  std::printf("frames %lld tracked %lld segments %d relocalizations %lld keyframes %lld\n",
              static_cast<long long>(s.frames), static_cast<long long>(s.frames_tracked), s.segments,
              static_cast<long long>(s.relocalizations), static_cast<long long>(s.keyframes_created));
  return 0;
}
