// ccm_agent: the collaborative SLAM agent binary. Runs the onboard monocular VO on a
// dataset folder, a simulated agent or a camera and, unless --standalone, streams its
// keyframes and points to ccm_server over DDS and integrates the map the server shares
// back (agent_runtime/agent_runner.h, agent_comm.h).
#include <CLI/CLI.hpp>
#include <glog/logging.h>
#include <opencv2/core/utility.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <iostream>

#include "agent_runtime/agent_runner.h"
#include "runtime_common/logging.h"
#include "runtime_common/runtime_cli.h"

namespace {
using namespace ccm;

volatile bool g_stop_flag = false;
void OnSignal(int) { g_stop_flag = true; }

int Fail(const std::string& message) {
  std::cerr << "error: " << message << "\n";
  return 2;
}

struct AgentArgs {
  agent::AgentConfig config;
  rt::SessionOptions session;
  std::string config_path;
  bool standalone = false;
  agent::RunOptions run;
};

// Options given on the command line win over the config file's keys.
struct GivenOnCommandLine {
  rt::DdsOptionsGiven dds;
  CLI::Option *id, *vocab, *no_sharing, *skip_late;
};

GivenOnCommandLine AddOptions(CLI::App* app, AgentArgs* a) {
  agent::AgentConfig& c = a->config;
  agent::RunOptions& run = a->run;
  GivenOnCommandLine g{};
  app->add_option("-c,--config", a->config_path, "YAML config file (keys: see docs/configuration.md)")
      ->check(CLI::ExistingFile);
  g.id = app->add_option("--agent-id", c.agent_id, "agent id, 1..65535 (overrides the config)");
  g.dds = rt::AddDdsOptions(app, &c, &a->session);
  app->add_flag("--standalone", a->standalone, "run the VO without DDS (no server)");
  app->add_option("--dataset", run.dataset, "dataset folder (EuRoC, TUM RGB-D or KITTI odometry)");
  app->add_option("--format", run.format, "dataset format: auto, euroc, tum, kitti")->capture_default_str();
  app->add_option("--calibration", run.calibration, "camera calibration YAML overriding the dataset's");
  app->add_option("--sim", run.sim_scenario, "fly a simulated agent of this scenario (hall3, disjoint2, repeated, FILE)");
  app->add_option("--sim-agent", run.sim_agent, "agent index in the scenario")->capture_default_str();
  app->add_option("--video", run.video,
                  "live camera (0, /dev/video0), GStreamer pipeline (\"... ! appsink\") or video file; needs --calibration");
  app->add_option("--ros2-image", run.ros2_image,
                  "a ROS 2 camera driver's sensor_msgs/Image topic (mono8, bgr8, rgb8, ...; docs/ros2.md)");
  app->add_option("--ros2-camera-info", run.ros2_camera_info,
                  "its sensor_msgs/CameraInfo topic (default: camera_info beside the image topic); --calibration wins");
  app->add_option("--ros2-domain", run.ros2_domain, "the camera's ROS 2 domain (default: $ROS_DOMAIN_ID, else 0)");
  app->add_option("--ros2-queue", run.ros2_queue, "images kept while tracking is busy; older ones are skipped")
      ->capture_default_str();
  app->add_option("--end-after", run.end_after_s,
                  "live input (--video DEVICE|PIPELINE, --ros2-image): end the flight after this many seconds without "
                  "a frame (a finished bag or pipeline; 0: wait for ever)")
      ->capture_default_str();
  app->add_option("--trajectory", run.trajectory_out, "write the per-frame trajectory (TUM format)");
  app->add_option("--keyframes", run.keyframes_out, "write the keyframe trajectory (TUM format)");
  app->add_option("--ground-truth", run.ground_truth_out, "write the input's ground truth of the processed frames (TUM)");
  app->add_option("--rate", run.rate, "playback: max, realtime or a speed factor")->capture_default_str();
  g.skip_late = app->add_flag("--skip-late-frames", run.skip_late_frames,
                              "paced input (--rate realtime) acts as a camera: a frame whose successor is due is skipped");
  app->add_option("--max-frames", run.max_frames, "stop after N frames (-1: all)")->capture_default_str();
  g.vocab = app->add_option("--vocab", c.vocabulary,
                            "bag-of-words vocabulary for relocalization (default: built-in; none: brute force)");
  app->add_flag("--no-acks", run.no_acks, "standalone: act as if the server never acknowledges (N+B, then drops)");
  app->add_option("--metrics", run.metrics_port,
                  "serve Prometheus metrics at http://BIND:PORT/metrics (0: any free port, printed; docs/monitoring.md)");
  app->add_option("--metrics-bind", run.metrics_bind, "address the metrics endpoint listens on (0.0.0.0: the network)")
      ->capture_default_str();
  app->add_option("--drain", run.drain_s, "connected: wait this long for the last acknowledgements [s]")
      ->capture_default_str();
  g.no_sharing = app->add_flag("--no-map-sharing", "do not integrate the keyframes the server sends back");
  return g;
}

// The config file's keys, overridden by the command line; then validation, logging and the
// run's options.
bool Resolve(const GivenOnCommandLine& g, AgentArgs* a, std::string* error) {
  agent::AgentConfig& config = a->config;
  agent::RunOptions& run = a->run;
  if (!a->config_path.empty()) {
    agent::AgentConfig from_file;
    if (!agent::LoadAgentConfig(a->config_path, &from_file, error)) return false;
    const agent::AgentConfig cli = config;
    config = from_file;
    rt::KeepGivenDdsOptions(g.dds, cli, &config);
    if (*g.id) config.agent_id = cli.agent_id;
    if (*g.vocab) config.vocabulary = cli.vocabulary;
  }
  if (*g.no_sharing) config.map_sharing = false;
  // The robot's camera from its config file, unless the command line names another input.
  if (run.dataset.empty() && run.sim_scenario.empty() && run.video.empty() && run.ros2_image.empty()) {
    if (!config.camera.empty()) run.video = config.camera;
    if (!config.ros2_image.empty()) {
      run.ros2_image = config.ros2_image;
      if (run.ros2_camera_info.empty()) run.ros2_camera_info = config.ros2_camera_info;
    }
    if (run.calibration.empty()) run.calibration = config.calibration;
  }
  if (run.ros2_domain < 0) run.ros2_domain = config.ros2_domain;
  if (!*g.skip_late) run.skip_late_frames = config.skip_late_frames;
  run.qos_file = config.qos_file;
  if (std::string problem = config.Validate(); !problem.empty()) return *error = problem, false;
  // One by default: OpenCV's pool (one worker per core) parallelizes the image pyramids of a
  // single small image, which costs more CPU in its workers than it saves the tracking thread
  // (docs/deployment.md "OpenCV's worker pool").
  if (config.opencv_threads > 0) cv::setNumThreads(config.opencv_threads);
  if (!rt::SetupLogging(config.log_level, error)) return false;
  run.agent_id = config.agent_id;
  run.vo = config.EffectiveVo();
  run.vocabulary = config.vocabulary;
  // A flight has no end: keep only what trajectories need when they are asked for.
  run.vo.record_frame_trajectory = !run.trajectory_out.empty() || !run.keyframes_out.empty();
  return true;
}

// Connected runs: the DDS session's options and ids of this process' life.
bool PrepareConnected(AgentArgs* a, std::string* error) {
  rt::SessionOptions& session = a->session;
  if (!rt::ResolveSession(a->config, &session, error)) return false;
  // A restarted agent with the same id must not reuse keyframe, point or segment ids the
  // server already holds (it would take new keyframes for resends). Seconds since 2024
  // (segments, 32 bits on the wire) and 100000 ids per second of clock (keyframes and
  // points; 48-bit counters) keep every life's ids above the previous one's.
  const auto now_s = std::chrono::duration_cast<std::chrono::seconds>(
                         std::chrono::system_clock::now().time_since_epoch()).count();
  const uint64_t life = static_cast<uint64_t>(std::max<int64_t>(1, now_s - 1704067200));
  a->run.vo.first_segment_counter = life;
  a->run.vo.first_id_counter = life * 100000;
  if (session.fault.enabled()) spdlog::warn("fault injection active: {}", session.fault.ToString());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  AgentArgs args;
  CLI::App app{"ccm_agent: collaborative monocular SLAM agent (CCM-SLAM on Fast DDS)"};
  const GivenOnCommandLine given = AddOptions(&app, &args);
  CLI11_PARSE(app, argc, argv);
  rt::SetUpGlog(argv[0]);
  std::string error;
  if (!Resolve(given, &args, &error)) return Fail(error);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  if (args.standalone) return agent::RunAgent(args.run, nullptr, nullptr, &g_stop_flag);
  if (!PrepareConnected(&args, &error)) return Fail(error);
  return agent::RunAgent(args.run, &args.config, &args.session, &g_stop_flag);
}
