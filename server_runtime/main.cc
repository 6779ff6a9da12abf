// ccm_server: the ground-station daemon. Receives the agents' keyframes and points over DDS
// (server_comm.h), runs the collaborative SLAM back-end on them (slam_core/server: map stack,
// place recognition, fusion, loop closure, global BA; stage threads in backend_runner.h),
// acknowledges what it processed and shares the map back. As a daemon (deploy/systemd/) it
// keeps its map stack in one file (--map-file): loaded at start, saved every autosave_s while
// running and on SIGTERM/SIGINT (a second signal exits at once, without saving). It
// publishes its status for `ccm_ctl status` every status_period_s. --out writes
// trajectories, the map and summaries on exit.
#include <CLI/CLI.hpp>
#include <glog/logging.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <thread>

#include "slam_core/common/install_paths.h"
#include "runtime_common/logging.h"
#include "server_runtime/backend_runner.h"
#include "server_runtime/map_view_server.h"
#include "server_runtime/server_comm.h"
#include "server_runtime/server_outputs.h"
#include "server_runtime/server_status.h"
#include "slam_core/place_recognition/vocabulary_io.h"

#ifndef CCM_DEFAULT_VOCABULARY
#define CCM_DEFAULT_VOCABULARY ""
#endif

namespace {
std::atomic<bool> g_stop{false};
// The first SIGTERM/SIGINT asks for a clean stop (finish queued work, save the map); a
// second one means the operator will not wait for that.
void OnSignal(int sig) {
  if (g_stop.exchange(true)) std::_Exit(128 + sig);
}

// Grows whenever the map stack changes (new keyframes, refinements, fusions, loops, BAs,
// removals): autosave skips a save when it has not moved.
int64_t StackVersion(const ccm::ServerBackend& backend) {
  const ccm::BackendStats s = backend.stats();
  int64_t v = s.fusions + s.loops + s.global_ba_applied + s.keyframes_removed;
  for (const auto& [id, c] : s.agents) v += c.keyframes_registered + c.points_registered + c.updates_applied;
  return v;
}

bool SaveMapStack(const ccm::ServerBackend& backend, const std::string& path, const char* why) {
  const auto t0 = std::chrono::steady_clock::now();
  std::error_code ec;
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  std::string error;
  if (!backend.Save(path, &error)) {
    spdlog::error("{}: saving the map stack failed: {}", why, error);
    return false;
  }
  size_t kfs = 0;
  const auto maps = backend.Maps();
  for (const auto& m : maps) kfs += m.keyframes;
  spdlog::info("{}: map stack saved to {} ({} maps, {} keyframes, {:.0f} ms)", why, path, maps.size(), kfs,
               std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  return true;
}

int Fail(const std::string& message, int code = 2) {
  std::cerr << "ccm_server: error: " << message << "\n";
  return code;
}

void LogProgress(const ccm::ServerBackend& backend, const ccm::server::ServerCommStats& comm) {
  const auto maps = backend.Maps();
  const auto stats = backend.stats();
  const auto queues = backend.queue_depths();
  std::string agents;
  for (const auto& [id, l] : comm.agents) {
    const auto c = stats.agents.count(id) ? stats.agents.at(id) : ccm::AgentCounters{};
    const size_t queued = queues.agent_batches.count(id) ? queues.agent_batches.at(id) : 0;
    agents += fmt::format(" | agent {}{}: KFs {} rx {} reg, queue {}, tracking {}", id, l.alive ? "" : " (gone)",
                          l.keyframes, c.keyframes_registered, queued, l.tracking_state);
  }
  size_t kfs = 0;
  for (const auto& m : maps) kfs += m.keyframes;
  spdlog::info("{:.0f} s: maps {} ({} KFs), fusions {}, loops {}, global BAs {}{}", comm.elapsed_s, maps.size(), kfs,
               stats.fusions, stats.loops, stats.global_ba_applied, agents);
}
}  // namespace

int main(int argc, char** argv) {
  using namespace ccm;
  server::ServerConfig config;
  rt::SessionOptions session;
  std::string config_path, out_dir;
  double duration_s = 0.0, idle_exit_s = 0.0, progress_s = 2.0;
  bool no_final_ba = false;
  server::MapViewServerOptions map_view;
  CLI::App app{"ccm_server: collaborative SLAM server (CCM-SLAM on Fast DDS)"};
  app.add_option("-c,--config", config_path, "YAML config file (keys: see docs/configuration.md)")
      ->check(CLI::ExistingFile);
  auto* domain_opt = app.add_option("--domain", config.domain_id, "DDS domain id (overrides the config)");
  auto* qos_opt = app.add_option("--qos", config.qos_file, "Fast DDS XML QoS profiles file (overrides the config)");
  auto* security_opt = app.add_option("--security-dir", config.security_dir,
                                     "DDS-Security directory of this participant (docs/security.md; overrides the config)");
  auto* log_opt = app.add_option("--log-level", config.log_level, "trace, debug, info, warn, error, off");
  auto* participant_opt = app.add_option("--participant-profile", config.participant_profile,
                                         "participant profile in the QoS file (discovery server: ccm_participant_ds_client)");
  auto* vocab_opt = app.add_option("--vocab", config.vocabulary, "bag-of-words vocabulary (default: the built-in one)");
  auto* load_opt = app.add_option("--load-map", config.load_map, "start from this saved map stack")
                       ->check(CLI::ExistingFile);
  auto* save_opt = app.add_option("--save-map", config.save_map, "save the map stack here on exit");
  auto* map_file_opt = app.add_option("--map-file", config.map_file,
                                      "daemon map stack: loaded if it exists, autosaved, saved on exit");
  auto* autosave_opt = app.add_option("--autosave", config.autosave_s, "autosave period [s] (0: only on exit)");
  app.add_option("--out", out_dir, "on exit write trajectories (TUM), summary.json, server.json, map.ply, map_top.png");
  app.add_flag("--no-final-ba", no_final_ba, "skip the global BA of every map on exit");
  app.add_option("--duration", duration_s, "stop after this many seconds (0: until Ctrl-C)");
  app.add_option("--idle-exit", idle_exit_s,
                 "stop once every agent has left and no data arrived for this long, after the first [s]");
  app.add_option("--progress", progress_s, "progress line period [s]")->capture_default_str();
  app.add_option("--drop", session.fault.drop_probability, "fault injection: drop probability of received datagrams");
  app.add_option("--delay-ms", session.fault.delay_ms, "fault injection: delay of received datagrams [ms]");
  server::AddMapViewOptions(&app, &map_view);
  CLI11_PARSE(app, argc, argv);
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = google::GLOG_ERROR;  // Ceres' rejected-step warnings are noise here
  FLAGS_logtostderr = true;

  std::string error;
  if (!config_path.empty()) {
    server::ServerConfig from_file;
    if (!server::LoadServerConfig(config_path, &from_file, &error)) return Fail(error);
    const server::ServerConfig cli = config;
    config = from_file;  // the command line wins over the file
    if (*domain_opt) config.domain_id = cli.domain_id;
    if (*qos_opt) config.qos_file = cli.qos_file;
    if (*security_opt) config.security_dir = cli.security_dir;
    if (*log_opt) config.log_level = cli.log_level;
    if (*participant_opt) config.participant_profile = cli.participant_profile;
    if (*vocab_opt) config.vocabulary = cli.vocabulary;
    if (*load_opt) config.load_map = cli.load_map;
    if (*save_opt) config.save_map = cli.save_map;
    if (*map_file_opt) config.map_file = cli.map_file;
    if (*autosave_opt) config.autosave_s = cli.autosave_s;
  }
  if (config.vocabulary.empty()) config.vocabulary = rt::FindDataFile(rt::kInstalledVocabulary, CCM_DEFAULT_VOCABULARY);
  if (const std::string problem = config.Validate(); !problem.empty()) return Fail(problem);
  if (const std::string problem = map_view.Validate(); map_view.port != -1 && !problem.empty()) return Fail(problem);
  if (config.vocabulary.empty()) return Fail("no vocabulary: give --vocab FILE (train one with ccm_vocab train)");
  if (!rt::SetupLogging(config.log_level, &error)) return Fail(error);
  if (!config.map_file.empty()) {
    if (config.save_map.empty()) config.save_map = config.map_file;
    if (config.load_map.empty()) {
      if (std::filesystem::exists(config.map_file)) {
        config.load_map = config.map_file;
      } else {
        spdlog::info("no saved map stack at {}: starting with an empty one", config.map_file);
      }
    }
  }
  if (session.fault.drop_probability == 0.0 && session.fault.delay_ms == 0.0) {
    auto env = rt::FaultOptions::FromEnvironment(&error);
    if (!env) return Fail(error);
    session.fault = *env;
  }
  session.domain_id = config.domain_id;
  session.qos_file = config.qos_file;
  session.security_dir = config.security_dir;
  session.participant_profile = config.participant_profile;

  auto loaded = LoadVocabularyFile(config.vocabulary, &error);
  if (!loaded) return Fail(error);
  auto vocabulary = std::make_shared<const Vocabulary>(std::move(*loaded));
  ServerOptions options;
  options.max_agents = config.max_agents;
  options.neighbourhood_k = config.neighbourhood_k;
  std::unique_ptr<ServerBackend> backend;
  if (!config.load_map.empty()) {
    backend = ServerBackend::Load(config.load_map, vocabulary, options, &error);
    if (!backend) return Fail(error, 1);
    size_t kfs = 0;
    for (const auto& m : backend->Maps()) kfs += m.keyframes;
    spdlog::info("loaded {}: {} maps, {} keyframes, {} agents", config.load_map, backend->Maps().size(), kfs,
                 backend->agents().size());
  } else {
    backend = std::make_unique<ServerBackend>(vocabulary, options);
  }
  auto runner = std::make_unique<server::BackendRunner>(backend.get());
  auto comm = server::ServerComm::Create(config, session, backend.get(), &error);
  if (!comm) return Fail(error, 1);
  auto status = server::StatusPublisher::Create(comm->session(), &error);
  if (!status) return Fail(error, 1);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  if (session.fault.enabled()) spdlog::warn("fault injection active: {}", session.fault.ToString());
  spdlog::info("server up on domain {} (QoS {}, vocabulary {}: {} words, max {} agents, map sharing k = {})",
               config.domain_id, comm->session().options().qos_file, config.vocabulary, vocabulary->num_words(),
               config.max_agents, config.map_sharing ? config.neighbourhood_k : 0);
  std::unique_ptr<server::MapViewServer> view;
  if (map_view.enabled()) {
    const server::ServerComm* comm_ptr = comm.get();
    view = server::MapViewServer::Start(map_view, backend.get(), [comm_ptr] {
      return server::MapViewHostStatus(comm_ptr->Stats(), comm_ptr->Traffic());
    }, &error);
    if (!view) return Fail(error, 1);
    spdlog::info("map view on {}", view->url());
  }
  comm->Start();

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto next_progress = start + std::chrono::duration<double>(progress_s);
  auto next_status = start;
  const auto status_period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(config.status_period_s));
  const auto autosave_period = std::chrono::duration<double>(config.autosave_s);
  auto next_autosave = start + std::chrono::duration_cast<Clock::duration>(autosave_period);
  server::DaemonInfo daemon;
  daemon.map_file = config.save_map;
  int64_t saved_version = StackVersion(*backend);
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const auto stats = comm->Stats();
    const auto now = Clock::now();
    if (now >= next_progress) {
      LogProgress(*backend, stats);
      next_progress = now + std::chrono::duration<double>(progress_s);
    }
    if (now >= next_status) {
      daemon.uptime_s = stats.elapsed_s;
      status->Publish(server::MakeServerStatus(*backend, stats, comm->Traffic(), daemon));
      next_status = now + status_period;
    }
    // Autosave from this thread while the stages run: MapPersistence::Save copies each map
    // under its shared structure lock, and the file is written to a temporary and renamed,
    // so a crash or power cut leaves the previous complete file.
    if (config.autosave_s > 0.0 && !config.save_map.empty() && now >= next_autosave) {
      const int64_t version = StackVersion(*backend);
      if (version != saved_version && SaveMapStack(*backend, config.save_map, "autosave")) {
        saved_version = version;
        daemon.last_save_s = stats.elapsed_s;
      }
      next_autosave = Clock::now() + std::chrono::duration_cast<Clock::duration>(autosave_period);
    }
    if (duration_s > 0.0 && stats.elapsed_s >= duration_s) break;
    const bool anyone_alive = std::any_of(stats.agents.begin(), stats.agents.end(), [](const auto& a) { return a.second.alive; });
    if (idle_exit_s > 0.0 && stats.last_data_s >= 0.0 && !anyone_alive && stats.elapsed_s - stats.last_data_s >= idle_exit_s &&
        backend->Idle()) {
      spdlog::info("every agent left and no data for {:.0f} s: stopping", idle_exit_s);
      break;
    }
  }
  spdlog::info("stopping{}: finishing queued work", g_stop ? " on a signal" : "");
  if (view) view->Stop();  // before the comm module its status reads
  comm->Stop();
  runner->Stop();
  backend->ProcessAllQueued();
  if (!no_final_ba) {
    for (const auto& m : backend->Maps()) {
      if (m.keyframes >= 3) backend->ScheduleGlobalBa(m.id);
    }
    backend->ProcessAllQueued();
  }
  const double wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  const auto comm_stats = comm->Stats();
  const auto traffic = comm->Traffic();
  LogProgress(*backend, comm_stats);
  int code = 0;
  if (!config.save_map.empty() && !SaveMapStack(*backend, config.save_map, "exit")) code = 1;
  if (!out_dir.empty()) {
    if (server::WriteServerOutputs(out_dir, *backend, comm_stats, traffic, wall_s, &error)) {
      spdlog::info("outputs in {}", out_dir);
    } else {
      spdlog::error("writing outputs failed: {}", error);
      code = 1;
    }
  }
  std::cout << server::CommSummaryJson(comm_stats, traffic, backend->stats()) << std::endl;
  return code;
}
