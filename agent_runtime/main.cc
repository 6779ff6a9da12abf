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

namespace {
volatile bool g_stop_flag = false;
void OnSignal(int) { g_stop_flag = true; }
}  // namespace

int main(int argc, char** argv) {
  using namespace ccm;
  agent::AgentConfig config;
  rt::SessionOptions session;
  std::string config_path;
  bool standalone = false;
  agent::RunOptions run;
  CLI::App app{"ccm_agent: collaborative monocular SLAM agent (CCM-SLAM on Fast DDS)"};
  app.add_option("-c,--config", config_path, "YAML config file (keys: see docs/configuration.md)")
      ->check(CLI::ExistingFile);
  auto* id_opt = app.add_option("--agent-id", config.agent_id, "agent id, 1..65535 (overrides the config)");
  auto* domain_opt = app.add_option("--domain", config.domain_id, "DDS domain id (overrides the config)");
  auto* qos_opt = app.add_option("--qos", config.qos_file, "Fast DDS XML QoS profiles file (overrides the config)");
  auto* security_opt = app.add_option("--security-dir", config.security_dir,
                                     "DDS-Security directory of this participant (docs/security.md; overrides the config)");
  auto* log_opt = app.add_option("--log-level", config.log_level, "trace, debug, info, warn, error, off");
  auto* participant_opt = app.add_option("--participant-profile", config.participant_profile,
                                         "participant profile in the QoS file (discovery server: ccm_participant_ds_client)");
  app.add_flag("--standalone", standalone, "run the VO without DDS (no server)");
  app.add_option("--dataset", run.dataset, "dataset folder (EuRoC, TUM RGB-D or KITTI odometry)");
  app.add_option("--format", run.format, "dataset format: auto, euroc, tum, kitti")->capture_default_str();
  app.add_option("--calibration", run.calibration, "camera calibration YAML overriding the dataset's");
  app.add_option("--sim", run.sim_scenario, "fly a simulated agent of this scenario (hall3, disjoint2, repeated, FILE)");
  app.add_option("--sim-agent", run.sim_agent, "agent index in the scenario")->capture_default_str();
  app.add_option("--video", run.video, "live camera (0, /dev/video0) or video file; needs --calibration");
  app.add_option("--trajectory", run.trajectory_out, "write the per-frame trajectory (TUM format)");
  app.add_option("--keyframes", run.keyframes_out, "write the keyframe trajectory (TUM format)");
  app.add_option("--ground-truth", run.ground_truth_out, "write the input's ground truth of the processed frames (TUM)");
  app.add_option("--rate", run.rate, "playback: max, realtime or a speed factor")->capture_default_str();
  app.add_option("--max-frames", run.max_frames, "stop after N frames (-1: all)")->capture_default_str();
  auto* vocab_opt = app.add_option("--vocab", config.vocabulary,
                                   "bag-of-words vocabulary for relocalization (default: built-in; none: brute force)");
  app.add_flag("--no-acks", run.no_acks, "standalone: act as if the server never acknowledges (N+B, then drops)");
  app.add_option("--drain", run.drain_s, "connected: wait this long for the last acknowledgements [s]")
      ->capture_default_str();
  auto* sharing_opt = app.add_flag("--no-map-sharing", "do not integrate the keyframes the server sends back");
  app.add_option("--drop", session.fault.drop_probability, "fault injection: drop probability of received datagrams");
  app.add_option("--delay-ms", session.fault.delay_ms, "fault injection: delay of received datagrams [ms]");
  CLI11_PARSE(app, argc, argv);
  // Ceres reports rejected trust-region steps (a point behind a camera) as glog warnings:
  // expected during optimization, noise for an operator. Keep its errors.
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = google::GLOG_ERROR;
  FLAGS_logtostderr = true;

  std::string error;
  if (!config_path.empty()) {
    agent::AgentConfig from_file;
    if (!agent::LoadAgentConfig(config_path, &from_file, &error)) {
      std::cerr << "error: " << error << "\n";
      return 2;
    }
    // Command-line values win over the file.
    const agent::AgentConfig cli = config;
    config = from_file;
    if (*id_opt) config.agent_id = cli.agent_id;
    if (*domain_opt) config.domain_id = cli.domain_id;
    if (*qos_opt) config.qos_file = cli.qos_file;
    if (*security_opt) config.security_dir = cli.security_dir;
    if (*log_opt) config.log_level = cli.log_level;
    if (*vocab_opt) config.vocabulary = cli.vocabulary;
    if (*participant_opt) config.participant_profile = cli.participant_profile;
  }
  if (*sharing_opt) config.map_sharing = false;
  // The robot's camera from its config file, unless the command line names another input.
  if (run.dataset.empty() && run.sim_scenario.empty() && run.video.empty() && !config.camera.empty()) {
    run.video = config.camera;
    if (run.calibration.empty()) run.calibration = config.calibration;
  }
  // Weak boards: OpenCV would otherwise start one worker per core for the image pyramids,
  // competing with tracking and local mapping (docs/deployment.md, budgets).
  if (config.opencv_threads > 0) cv::setNumThreads(config.opencv_threads);
  if (const std::string problem = config.Validate(); !problem.empty()) {
    std::cerr << "error: " << problem << "\n";
    return 2;
  }
  if (!rt::SetupLogging(config.log_level, &error)) {
    std::cerr << "error: " << error << "\n";
    return 2;
  }
  run.agent_id = config.agent_id;
  run.vo = config.EffectiveVo();
  run.vocabulary = config.vocabulary;
  // A flight has no end: keep only what trajectories need when they are asked for.
  run.vo.record_frame_trajectory = !run.trajectory_out.empty() || !run.keyframes_out.empty();
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  if (standalone) return agent::RunAgent(run, nullptr, nullptr, &g_stop_flag);

  if (session.fault.drop_probability == 0.0 && session.fault.delay_ms == 0.0) {
    auto env = rt::FaultOptions::FromEnvironment(&error);
    if (!env) {
      std::cerr << "error: " << error << "\n";
      return 2;
    }
    session.fault = *env;
  }
  session.domain_id = config.domain_id;
  session.qos_file = config.qos_file;
  session.security_dir = config.security_dir;
  session.participant_profile = config.participant_profile;
  // Ids of this process' life: a restarted agent with the same id must not reuse keyframe,
  // point or segment ids the server already holds (it would take new keyframes for resends).
  // Seconds since 2024 (segments, 32 bits on the wire) and 100000 ids per second of clock
  // (keyframes and points; 48-bit counters) keep every life's ids above the previous one's.
  const auto now_s = std::chrono::duration_cast<std::chrono::seconds>(
                         std::chrono::system_clock::now().time_since_epoch()).count();
  const uint64_t life = static_cast<uint64_t>(std::max<int64_t>(1, now_s - 1704067200));
  run.vo.first_segment_counter = life;
  run.vo.first_id_counter = life * 100000;
  if (session.fault.enabled()) spdlog::warn("fault injection active: {}", session.fault.ToString());
  return agent::RunAgent(run, &config, &session, &g_stop_flag);
}
