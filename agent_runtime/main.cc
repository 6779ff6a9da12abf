// ccm_agent: the collaborative SLAM agent binary.
//  * `--standalone`: monocular VO without DDS on a dataset or a simulated agent; writes
//    trajectories (see agent_runtime/standalone_runner.h).
//  * `--link-demo N`: streams N synthetic full keyframes to the server through the real
//    protocol (acks, resends, status) so links and QoS can be checked.
#include <CLI/CLI.hpp>
#include <glog/logging.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <csignal>
#include <iostream>
#include <thread>

#include "agent_runtime/agent_comm.h"
#include "agent_runtime/standalone_runner.h"
#include "runtime_common/logging.h"
#include "runtime_common/synthetic_msgs.h"

namespace {
std::atomic<bool> g_stop{false};
volatile bool g_stop_flag = false;  // same flag for the standalone runner
void OnSignal(int) {
  g_stop = true;
  g_stop_flag = true;
}
}  // namespace

int main(int argc, char** argv) {
  using namespace ccm;
  agent::AgentConfig config;
  rt::SessionOptions session;
  std::string config_path;
  int link_demo = 0;
  double duration_s = 0.0, drain_s = 30.0;
  CLI::App app{"ccm_agent: collaborative monocular SLAM agent (CCM-SLAM on Fast DDS)"};
  app.add_option("-c,--config", config_path, "YAML config file (keys: see docs/configuration.md)")
      ->check(CLI::ExistingFile);
  auto* id_opt = app.add_option("--agent-id", config.agent_id, "agent id, 1..65535 (overrides the config)");
  auto* domain_opt = app.add_option("--domain", config.domain_id, "DDS domain id (overrides the config)");
  auto* qos_opt = app.add_option("--qos", config.qos_file, "Fast DDS XML QoS profiles file (overrides the config)");
  auto* log_opt = app.add_option("--log-level", config.log_level, "trace, debug, info, warn, error, off");
  app.add_option("--link-demo", link_demo, "stream N synthetic keyframes through the protocol, then exit");
  app.add_option("--duration", duration_s, "stop after this many seconds (0: until Ctrl-C or done)");
  app.add_option("--drain", drain_s, "link demo: wait this long for the last acks [s]")->capture_default_str();
  app.add_option("--drop", session.fault.drop_probability, "fault injection: drop probability of received datagrams");
  app.add_option("--delay-ms", session.fault.delay_ms, "fault injection: delay of received datagrams [ms]");
  bool standalone = false;
  agent::StandaloneOptions sa;
  auto* sa_group = app.add_option_group("standalone", "VO without a server (--standalone)");
  sa_group->add_flag("--standalone", standalone, "run the VO without DDS on --dataset or --sim");
  sa_group->add_option("--dataset", sa.dataset, "dataset folder (EuRoC, TUM RGB-D or KITTI odometry)");
  sa_group->add_option("--format", sa.format, "dataset format: auto, euroc, tum, kitti")->capture_default_str();
  sa_group->add_option("--calibration", sa.calibration, "camera calibration YAML overriding the dataset's");
  sa_group->add_option("--sim", sa.sim_scenario, "fly a simulated agent of this scenario (hall3, disjoint2, repeated, FILE)");
  sa_group->add_option("--sim-agent", sa.sim_agent, "agent index in the scenario")->capture_default_str();
  sa_group->add_option("--video", sa.video, "live camera (0, /dev/video0) or video file; needs --calibration");
  sa_group->add_option("--trajectory", sa.trajectory_out, "write the per-frame trajectory (TUM format)");
  sa_group->add_option("--keyframes", sa.keyframes_out, "write the keyframe trajectory (TUM format)");
  sa_group->add_option("--ground-truth", sa.ground_truth_out, "write the input's ground truth of the processed frames (TUM)");
  sa_group->add_option("--rate", sa.rate, "playback: max, realtime or a speed factor")->capture_default_str();
  sa_group->add_option("--max-frames", sa.max_frames, "stop after N frames (-1: all)")->capture_default_str();
  sa_group->add_flag("--no-acks", sa.no_acks, "act as if the server never acknowledges (local map grows to N+B, then drops)");
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
    if (*log_opt) config.log_level = cli.log_level;
  }
  if (const std::string problem = config.Validate(); !problem.empty()) {
    std::cerr << "error: " << problem << "\n";
    return 2;
  }
  if (!rt::SetupLogging(config.log_level, &error)) {
    std::cerr << "error: " << error << "\n";
    return 2;
  }
  if (standalone) {
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    sa.agent_id = config.agent_id;
    sa.vo = config.vo;
    sa.vo.bound.max_keyframes = config.max_keyframes;
    sa.vo.bound.max_unacked_buffer = config.buffer_keyframes;
    return agent::RunStandalone(sa, &g_stop_flag);
  }
  if (session.fault.drop_probability == 0.0 && session.fault.delay_ms == 0.0) {
    auto env = rt::FaultOptions::FromEnvironment(&error);
    if (!env) { std::cerr << "error: " << error << "\n"; return 2; }
    session.fault = *env;
  }
  session.domain_id = config.domain_id;
  session.qos_file = config.qos_file;
  auto comm = agent::AgentComm::Create(config, session, &error);
  if (!comm) {
    std::cerr << "error: " << error << "\n";
    return 1;
  }
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  if (session.fault.enabled()) spdlog::warn("fault injection active: {}", session.fault.ToString());
  spdlog::info("agent {} up on domain {}", config.agent_id, config.domain_id);
  comm->Start();

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto period = std::chrono::duration<double>(1.0 / config.keyframe_rate_hz);
  auto elapsed = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  int produced = 0;
  auto last_progress = Clock::now();
  while (!g_stop && (duration_s <= 0.0 || elapsed() < duration_s)) {
    if (produced < link_demo) {
      comm->Send(synthetic::MakeKeyframe(static_cast<std::uint16_t>(config.agent_id), produced,
                                         config.features_per_keyframe, config.features_per_keyframe / 3));
      ++produced;
    } else if (link_demo > 0 && (comm->AllAcked() || elapsed() > produced / config.keyframe_rate_hz + drain_s)) {
      break;
    }
    if (Clock::now() - last_progress > std::chrono::seconds(2)) {
      const auto s = comm->Stats();
      spdlog::info("agent {}: sent {} resent {} acked {} unacked {} server msgs {} (servers matched: {})",
                   config.agent_id, s.kfs_sent, s.kfs_resent, s.kfs_acked, s.kfs_unacked, s.server_msgs,
                   comm->matched_servers());
      last_progress = Clock::now();
    }
    std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(period * (produced + 1)));
  }
  comm->Stop();
  const auto s = comm->Stats();
  nlohmann::json summary = {{"agent_id", config.agent_id}, {"kfs_sent", s.kfs_sent}, {"kfs_resent", s.kfs_resent},
                            {"kfs_acked", s.kfs_acked}, {"kfs_unacked", s.kfs_unacked}, {"kfs_lost", s.kfs_lost},
                            {"write_failures", s.write_failures}, {"server_msgs", s.server_msgs}};
  for (const auto& t : comm->Traffic()) summary["traffic"][t.topic + ":" + t.direction] = t.payload_bytes;
  std::cout << summary.dump() << std::endl;
  return (link_demo > 0 && s.kfs_unacked > 0) ? 3 : 0;
}
