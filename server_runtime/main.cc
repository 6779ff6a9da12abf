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

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <set>
#include <thread>

#include "slam_core/common/install_paths.h"
#include "runtime_common/logging.h"
#include "runtime_common/process_memory.h"
#include "runtime_common/runtime_cli.h"
#include "server_runtime/backend_runner.h"
#include "server_runtime/map_view_server.h"
#include "server_runtime/mission_timeline.h"
#include "server_runtime/ros2_outputs.h"
#include "server_runtime/server_comm.h"
#include "server_runtime/server_outputs.h"
#include "server_runtime/server_status.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "slam_core/server/map_persistence.h"
#include "slam_core/server/stack_file.h"

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
  const ccm::BackendStats s = backend.Status().stats;
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
  const ccm::MapStackSnapshot snapshot = backend.Snapshot();
  if (!ccm::MapPersistence::Save(snapshot, path, &error)) {
    spdlog::error("{}: saving the map stack failed: {} (the last complete file stays; agents keep what it lacks "
                  "until a save succeeds)",
                  why, error);
    return false;
  }
  size_t kfs = 0;
  const auto maps = snapshot.Summaries();
  for (const auto& m : maps) kfs += m.keyframes;
  spdlog::info("{}: map stack saved to {} ({} maps, {} keyframes, {:.0f} ms)", why, path, maps.size(), kfs,
               std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  return true;
}

int Fail(const std::string& message, int code = 2) {
  std::cerr << "ccm_server: error: " << message << "\n";
  return code;
}

void LogProgress(const ccm::BackendStatus& status, const std::vector<ccm::MapSummary>& maps,
                 const ccm::server::ServerCommStats& comm) {
  const auto& stats = status.stats;
  const auto& queues = status.queues;
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
using namespace ccm;

// The command line and what it resolves to.
struct ServerArgs {
  server::ServerConfig config;
  rt::SessionOptions session;
  std::string config_path, out_dir;
  double duration_s = 0.0, idle_exit_s = 0.0, progress_s = 2.0;
  bool no_final_ba = false;
  server::MapViewServerOptions map_view;
};

// Options given on the command line win over the config file's keys.
struct GivenOnCommandLine {
  rt::DdsOptionsGiven dds;
  CLI::Option *vocab, *load, *save, *map_file, *autosave, *ros2;
};

GivenOnCommandLine AddOptions(CLI::App* app, ServerArgs* a) {
  server::ServerConfig& c = a->config;
  GivenOnCommandLine g{};
  app->add_option("-c,--config", a->config_path, "YAML config file (keys: see docs/configuration.md)")
      ->check(CLI::ExistingFile);
  g.dds = rt::AddDdsOptions(app, &c, &a->session);
  g.vocab = app->add_option("--vocab", c.vocabulary, "bag-of-words vocabulary (default: the built-in one)");
  g.load = app->add_option("--load-map", c.load_map, "start from this saved map stack")->check(CLI::ExistingFile);
  g.save = app->add_option("--save-map", c.save_map, "save the map stack here on exit");
  g.map_file = app->add_option("--map-file", c.map_file, "daemon map stack: loaded if it exists, autosaved, saved on exit");
  g.autosave = app->add_option("--autosave", c.autosave_s, "autosave period [s] (0: only on exit)");
  app->add_option("--out", a->out_dir,
                  "on exit write trajectories (TUM), summary.json, server.json, map.ply, map_top.png");
  app->add_flag("--no-final-ba", a->no_final_ba,
                "skip the end-of-run work on exit: the sweep of repeated passes and the global BA of every map");
  g.ros2 = app->add_flag("--ros2", c.ros2_outputs,
                         "publish paths, poses, tf and the map for ROS 2 tools on the domain (docs/ros2.md)");
  app->add_option("--duration", a->duration_s, "stop after this many seconds (0: until Ctrl-C)");
  app->add_option("--idle-exit", a->idle_exit_s,
                  "stop once every agent has left and no data arrived for this long, after the first [s]");
  app->add_option("--progress", a->progress_s, "progress line period [s]")->capture_default_str();
  server::AddMapViewOptions(app, &a->map_view);
  return g;
}

// The config file's keys, overridden by what the command line gave.
bool MergeConfigFile(const GivenOnCommandLine& g, ServerArgs* a, std::string* error) {
  if (a->config_path.empty()) return true;
  server::ServerConfig from_file;
  if (!server::LoadServerConfig(a->config_path, &from_file, error)) return false;
  const server::ServerConfig cli = a->config;
  server::ServerConfig& c = a->config;
  c = from_file;
  rt::KeepGivenDdsOptions(g.dds, cli, &c);
  if (*g.vocab) c.vocabulary = cli.vocabulary;
  if (*g.load) c.load_map = cli.load_map;
  if (*g.save) c.save_map = cli.save_map;
  if (*g.map_file) c.map_file = cli.map_file;
  if (*g.autosave) c.autosave_s = cli.autosave_s;
  if (*g.ros2) c.ros2_outputs = true;
  return true;
}

// Defaults that depend on other keys (vocabulary, map file, fault injection from the
// environment), validation, logging, and the DDS session's options.
bool Resolve(ServerArgs* a, std::string* error) {
  server::ServerConfig& c = a->config;
  if (c.vocabulary.empty()) c.vocabulary = rt::FindDataFile(rt::kInstalledVocabulary, CCM_DEFAULT_VOCABULARY);
  if (std::string problem = c.Validate(); !problem.empty()) return *error = problem, false;
  if (std::string problem = a->map_view.Validate(); a->map_view.port != -1 && !problem.empty()) {
    return *error = problem, false;
  }
  if (c.vocabulary.empty()) return *error = "no vocabulary: give --vocab FILE (train one with ccm_vocab train)", false;
  if (!rt::SetupLogging(c.log_level, error)) return false;
  if (!c.map_file.empty()) {
    if (c.save_map.empty()) c.save_map = c.map_file;
    if (c.load_map.empty()) {
      // The previous generation alone is left when the newest could never be completed.
      if (std::filesystem::exists(c.map_file) || std::filesystem::exists(PreviousGeneration(c.map_file))) {
        c.load_map = c.map_file;
      } else {
        spdlog::info("no saved map stack at {}: starting with an empty one", c.map_file);
      }
    }
  }
  return rt::ResolveSession(c, &a->session, error);
}

// The back-end, empty or loaded from the saved map stack.
std::unique_ptr<ServerBackend> OpenBackend(const server::ServerConfig& config,
                                           std::shared_ptr<const Vocabulary> vocabulary, std::string* error) {
  ServerOptions options;
  options.max_agents = config.max_agents;
  options.agent_slot_release_s = config.agent_slot_release_s;
  options.neighbourhood_k = config.neighbourhood_k;
  options.share_own_keyframes_after_s = config.share_own_keyframes_after_s;
  options.optimization.global_ba_max_free_keyframes = config.global_ba_max_free_keyframes;
  options.optimization.global_ba_min_parallax_deg = config.global_ba_min_parallax_deg;
  options.optimization.global_ba_low_parallax_inverse_depth = config.global_ba_low_parallax_inverse_depth;
  options.redundancy.revisit_distance_ratio = config.revisit_distance_ratio;
  if (config.load_map.empty()) return std::make_unique<ServerBackend>(vocabulary, options);
  std::string warning;
  auto backend = LoadBackend(config.load_map, vocabulary, options, error, &warning);
  if (!backend) return nullptr;
  if (!warning.empty()) spdlog::warn("{}", warning);
  size_t kfs = 0;
  const MapStackSnapshot loaded = backend->Snapshot();
  const auto maps = loaded.Summaries();
  for (const auto& m : maps) kfs += m.keyframes;
  // The agents the file knows (their handlers): none has submitted to this process yet.
  std::set<AgentId> agents;
  for (const AgentHandler& h : loaded.handlers) agents.insert(h.agent);
  spdlog::info("loaded {}: {} maps, {} keyframes, {} agents", config.load_map, maps.size(), kfs, agents.size());
  return backend;
}

// Autosave's course for /metrics: written by the main thread, read by the map view's HTTP
// threads (atomics; no lock).
struct AutosaveFacts {
  std::atomic<double> last_s{-1.0};  // comm elapsed time of the last save or unchanged check
  std::atomic<int64_t> failures{0};
};

// What runs while the daemon is up. Destroyed in reverse order: the map view and the status
// writer before the comm module, the comm module before the stage threads and the back-end.
struct Services {
  size_t vocabulary_words = 0;  // for the start-up line
  std::unique_ptr<ServerBackend> backend;
  std::unique_ptr<server::BackendRunner> runner;
  std::unique_ptr<server::ServerComm> comm;
  std::unique_ptr<server::StatusPublisher> status;
  std::unique_ptr<server::MapViewServer> view;
  std::unique_ptr<server::Ros2Outputs> ros2;  // --ros2
  std::shared_ptr<AutosaveFacts> autosave = std::make_shared<AutosaveFacts>();
};

// Everything after the back-end: stage threads, DDS, status writer, map view; then intake starts.
bool StartServices(const ServerArgs& a, Services* s, std::string* error) {
  s->runner = std::make_unique<server::BackendRunner>(s->backend.get());
  s->comm = server::ServerComm::Create(a.config, a.session, s->backend.get(), error);
  if (!s->comm) return false;
  s->status = server::StatusPublisher::Create(s->comm->session(), error);
  if (!s->status) return false;
  if (a.config.ros2_outputs) {
    s->ros2 = server::Ros2Outputs::CreateWithOwnParticipant(s->comm->session().options(), a.config.Ros2Options(), error);
    if (!s->ros2) return false;
    spdlog::info("ROS 2 outputs on domain {}: rt/tf, rt/ccm/map_points, rt/ccm/agent_<id>/path and /pose (docs/ros2.md)",
                 s->ros2->domain_id());
  }
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  // A file-size limit (ulimit -f, a quota) must fail the save, not kill the ground station:
  // the write then returns EFBIG, autosave logs it and tries again at its next period.
  std::signal(SIGXFSZ, SIG_IGN);
  if (a.session.fault.enabled()) spdlog::warn("fault injection active: {}", a.session.fault.ToString());
  spdlog::info("server up on domain {} (QoS {}, vocabulary {}: {} words, max {} agents, map sharing k = {})",
               a.config.domain_id, s->comm->session().options().qos_file, a.config.vocabulary,
               s->vocabulary_words, a.config.max_agents,
               a.config.map_sharing ? a.config.neighbourhood_k : 0);
  if (a.map_view.enabled()) {
    const server::ServerComm* comm = s->comm.get();
    const bool autosaving = a.config.autosave_s > 0.0 && !a.config.save_map.empty();
    s->view = server::MapViewServer::Start(a.map_view, s->backend.get(), [comm, autosaving, facts = s->autosave] {
      const server::ServerCommStats stats = comm->Stats();
      nlohmann::json host = server::MapViewHostStatus(stats, comm->Traffic());
      if (autosaving) {
        const double last = facts->last_s.load();
        host["autosave_age_s"] = last < 0.0 ? -1.0 : std::round((stats.elapsed_s - last) * 10.0) / 10.0;
        host["autosave_failures"] = facts->failures.load();
      }
      return host;
    }, error);
    if (!s->view) return false;
    spdlog::info("map view on {}", s->view->url());
  }
  s->comm->Start();
  return true;
}

// The main thread's duties until a signal, --duration or --idle-exit: progress lines, the
// status sample for ccm_ctl, autosave. Autosave runs while the stages run:
// MapPersistence::Save copies each map under its shared structure lock, and the file is
// written to a temporary and renamed, so a crash or power cut leaves the previous file.
void RunUntilStopped(const ServerArgs& a, const Services& s) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto seconds = [](double s) { return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); };
  auto next_progress = start + seconds(a.progress_s);
  auto next_status = start;
  auto next_autosave = start + seconds(a.config.autosave_s);
  server::DaemonInfo daemon;
  daemon.map_file = a.config.save_map;
  int64_t saved_version = StackVersion(*s.backend);
  // The mission's course, a row per progress period (server_runtime/mission_timeline.h).
  server::MissionTimeline timeline;
  server::MissionTimelineFile timeline_file;
  if (!a.out_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(a.out_dir, ec);
    std::string error;
    if (!timeline_file.Open(a.out_dir + "/timeline.jsonl", &error)) spdlog::warn("{}", error);
  }
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const auto stats = s.comm->Stats();
    const auto now = Clock::now();
    if (now >= next_progress) {
      const BackendStatus status = s.backend->Status();
      const std::vector<MapSummary> maps = s.backend->Snapshot().Summaries();
      LogProgress(status, maps, stats);
      if (timeline_file.is_open()) timeline_file.Append(timeline.Row(stats.elapsed_s, rt::CurrentRssMb(), status, maps));
      next_progress = now + seconds(a.progress_s);
    }
    if (now >= next_status) {
      daemon.uptime_s = stats.elapsed_s;
      s.status->Publish(server::MakeServerStatus(*s.backend, stats, s.comm->Traffic(), daemon));
      next_status = now + seconds(a.config.status_period_s);
    }
    if (s.ros2) {
      std::string ros2_error;
      if (!s.ros2->PublishDue(*s.backend, stats.elapsed_s, &ros2_error)) spdlog::warn("ROS 2 outputs: {}", ros2_error);
    }
    if (a.config.autosave_s > 0.0 && !a.config.save_map.empty() && now >= next_autosave) {
      // Persisted acks (docs/protocol.md): every ack written so far is for a keyframe that
      // is in the stack and counted in its version (the back-end counts before it acks), so
      // once a snapshot taken after this point is on disk, or nothing changed since the
      // last save, the agents may let those keyframes go.
      const uint64_t acked_through = s.comm->AckSeqIssued();
      const int64_t version = StackVersion(*s.backend);
      if (version == saved_version) {
        s.comm->OnPersisted(acked_through);
        s.autosave->last_s = stats.elapsed_s;
      } else if (SaveMapStack(*s.backend, a.config.save_map, "autosave")) {
        saved_version = version;
        daemon.last_save_s = stats.elapsed_s;
        s.comm->OnPersisted(acked_through);
        s.autosave->last_s = stats.elapsed_s;
      } else {
        ++s.autosave->failures;
      }
      next_autosave = Clock::now() + seconds(a.config.autosave_s);
    }
    if (a.duration_s > 0.0 && stats.elapsed_s >= a.duration_s) break;
    const bool anyone_alive =
        std::any_of(stats.agents.begin(), stats.agents.end(), [](const auto& agent) { return agent.second.alive; });
    if (a.idle_exit_s > 0.0 && stats.last_data_s >= 0.0 && !anyone_alive &&
        stats.elapsed_s - stats.last_data_s >= a.idle_exit_s && s.backend->Status().idle) {
      spdlog::info("every agent left and no data for {:.0f} s: stopping", a.idle_exit_s);
      break;
    }
  }
}

// Stops intake, finishes the queued work (and the end of the run: ScheduleFinish), saves the
// map stack and writes the outputs. Returns the exit code.
int Shutdown(const ServerArgs& a, Services* s, std::chrono::steady_clock::time_point start) {
  spdlog::info("stopping{}: finishing queued work", g_stop ? " on a signal" : "");
  if (s->view) s->view->Stop();  // before the comm module its status reads
  s->comm->Stop();
  s->runner->Stop();
  ServerBackend& backend = *s->backend;
  backend.ProcessAllQueued();
  if (!a.no_final_ba) {
    backend.ScheduleFinish();  // the revisit sweep and a global BA of every map
    backend.ProcessAllQueued();
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto comm_stats = s->comm->Stats();
  const auto traffic = s->comm->Traffic();
  LogProgress(backend.Status(), backend.Snapshot().Summaries(), comm_stats);
  int code = 0;
  if (!a.config.save_map.empty() && !SaveMapStack(backend, a.config.save_map, "exit")) code = 1;
  std::string error;
  if (!a.out_dir.empty()) {
    if (server::WriteServerOutputs(a.out_dir, backend, comm_stats, traffic, wall_s, &error)) {
      spdlog::info("outputs in {}", a.out_dir);
    } else {
      spdlog::error("writing outputs failed: {}", error);
      code = 1;
    }
  }
  std::cout << server::CommSummaryJson(comm_stats, traffic, backend.Status().stats) << std::endl;
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  ServerArgs args;
  CLI::App app{"ccm_server: collaborative SLAM server (CCM-SLAM on Fast DDS)"};
  const GivenOnCommandLine given = AddOptions(&app, &args);
  CLI11_PARSE(app, argc, argv);
  rt::SetUpGlog(argv[0]);
  std::string error;
  if (!MergeConfigFile(given, &args, &error) || !Resolve(&args, &error)) return Fail(error);
  auto vocabulary = LoadVocabularyFile(args.config.vocabulary, &error);
  if (!vocabulary) return Fail(error);
  Services services;
  services.vocabulary_words = vocabulary->num_words();
  services.backend =
      OpenBackend(args.config, std::make_shared<const Vocabulary>(std::move(*vocabulary)), &error);
  if (!services.backend || !StartServices(args, &services, &error)) return Fail(error, 1);
  const auto start = std::chrono::steady_clock::now();
  RunUntilStopped(args, services);
  return Shutdown(args, &services, start);
}
