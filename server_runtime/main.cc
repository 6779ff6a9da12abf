// ccm_server: the ground-station daemon. This version runs the communication module: it
// receives keyframes and status from any number of agents and acknowledges them; the map
// stack, place recognition and optimization plug in behind it.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <csignal>
#include <iostream>
#include <thread>

#include "runtime_common/logging.h"
#include "server_runtime/server_comm.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  using namespace ccm;
  server::ServerConfig config;
  rt::SessionOptions session;
  std::string config_path;
  double duration_s = 0.0, idle_exit_s = 0.0;
  CLI::App app{"ccm_server: collaborative SLAM server (CCM-SLAM on Fast DDS)"};
  app.add_option("-c,--config", config_path, "YAML config file (keys: see docs/configuration.md)")
      ->check(CLI::ExistingFile);
  auto* domain_opt = app.add_option("--domain", config.domain_id, "DDS domain id (overrides the config)");
  auto* qos_opt = app.add_option("--qos", config.qos_file, "Fast DDS XML QoS profiles file (overrides the config)");
  auto* log_opt = app.add_option("--log-level", config.log_level, "trace, debug, info, warn, error, off");
  app.add_option("--duration", duration_s, "stop after this many seconds (0: until Ctrl-C)");
  app.add_option("--idle-exit", idle_exit_s, "stop once no keyframe arrived for this long, after the first [s]");
  app.add_option("--drop", session.fault.drop_probability, "fault injection: drop probability of received datagrams");
  app.add_option("--delay-ms", session.fault.delay_ms, "fault injection: delay of received datagrams [ms]");
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (!config_path.empty()) {
    server::ServerConfig from_file;
    if (!server::LoadServerConfig(config_path, &from_file, &error)) {
      std::cerr << "error: " << error << "\n";
      return 2;
    }
    const server::ServerConfig cli = config;
    config = from_file;
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
  if (session.fault.drop_probability == 0.0 && session.fault.delay_ms == 0.0) {
    auto env = rt::FaultOptions::FromEnvironment(&error);
    if (!env) { std::cerr << "error: " << error << "\n"; return 2; }
    session.fault = *env;
  }
  session.domain_id = config.domain_id;
  session.qos_file = config.qos_file;
  auto comm = server::ServerComm::Create(config, session, &error);
  if (!comm) {
    std::cerr << "error: " << error << "\n";
    return 1;
  }
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  if (session.fault.enabled()) spdlog::warn("fault injection active: {}", session.fault.ToString());
  spdlog::info("server up on domain {}", config.domain_id);
  comm->Start();

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  std::size_t last_total = 0;
  auto last_change = Clock::now();
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::seconds(1));  // reporting cadence of the main thread
    const auto stats = comm->Stats();
    std::size_t total = 0;
    for (const auto& [id, agent] : stats.agents) {
      total += agent.keyframes.size() + agent.duplicates;
      spdlog::info("agent {}: {} keyframes ({} duplicates), {} status msgs", id, agent.keyframes.size(),
                   agent.duplicates, agent.status_msgs);
    }
    if (total != last_total) {
      last_total = total;
      last_change = Clock::now();
    }
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    if (duration_s > 0.0 && elapsed >= duration_s) break;
    if (idle_exit_s > 0.0 && total > 0 && std::chrono::duration<double>(Clock::now() - last_change).count() >= idle_exit_s) break;
  }
  comm->Stop();
  const auto stats = comm->Stats();
  nlohmann::json summary = {{"messages_sent", stats.messages_sent}, {"bad_version", stats.bad_version}};
  for (const auto& [id, agent] : stats.agents) {
    summary["agents"][std::to_string(id)] = {{"keyframes", agent.keyframes.size()}, {"duplicates", agent.duplicates},
                                             {"status_msgs", agent.status_msgs}};
  }
  std::cout << summary.dump() << std::endl;
  return 0;
}
