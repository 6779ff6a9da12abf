// ccm_fleet: a team of recorded agents on the wire (issue 30). Plays the keyframe streams of
// one or more recordings (ccm_replay --record, bench_fusion --record) to a real ccm_server
// over DDS, each recorded agent as an agent of its own (own participant, id, acks, resends,
// map sharing; agent_runtime/recorded_data_source.h) at its recorded pace, so one machine can
// load a ground station with 16 and more agents without running their VOs. Then, with
// --score, it scores the map the server saved against the recordings' ground truth.
//
//   ccm_server --domain 7 --save-map /tmp/fleet.ccmmap --out /tmp/server &
//   ccm_fleet --domain 7 --recording a.ccmrec --recording b.ccmrec --out /tmp/fleet
//   kill -INT %1; wait
//   ccm_fleet --score /tmp/fleet.ccmmap --recording a.ccmrec --recording b.ccmrec --out /tmp/fleet
//   ccm_fleet --offline --recording a.ccmrec --recording b.ccmrec --out /tmp/fleet   # the same streams
//                                                      # through ccm_replay's deterministic engine
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "agent_runtime/agent_comm.h"
#include "agent_runtime/recorded_data_source.h"
#include "runtime_common/logging.h"
#include "runtime_common/runtime_cli.h"
#include "slam_core/common/install_paths.h"
#include "slam_core/common/stopwatch.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "slam_core/server/map_persistence.h"
#include "tools/fleet/fleet_team.h"

#ifndef CCM_DEFAULT_VOCABULARY
#define CCM_DEFAULT_VOCABULARY ""
#endif

namespace {

using namespace ccm;
volatile bool g_stop = false;
void OnSignal(int) { g_stop = true; }

struct Args {
  agent::AgentConfig config;
  rt::SessionOptions session;
  std::string config_path;
  fleet::TeamOptions team;
  std::string out = "fleet-out";
  std::string score_map;
  bool offline = false;
  ServerOptions offline_server;
  std::string vocabulary = rt::FindDataFile(rt::kInstalledVocabulary, CCM_DEFAULT_VOCABULARY);
  double start_delay_s = 3.0;
  double drain_s = 60.0;
  double progress_s = 5.0;
};

int Fail(const std::string& message, int code = 2) {
  std::fprintf(stderr, "error: %s\n", message.c_str());
  return code;
}

rt::DdsOptionsGiven AddOptions(CLI::App* app, Args* a) {
  app->add_option("--recording", a->team.recordings, "recorded keyframe streams (.ccmrec); repeat for more teams")
      ->required()
      ->check(CLI::ExistingFile);
  app->add_option("--agents", a->team.max_agents, "play only the first N agents of all recordings (0: all)")
      ->capture_default_str();
  app->add_option("--speed", a->team.speed, "playback speed (1: the recorded pace)")->capture_default_str();
  app->add_option("--stagger", a->team.stagger_s, "each further recording starts this many seconds later")
      ->capture_default_str();
  app->add_option("-c,--config", a->config_path, "ccm_agent YAML config: link settings of every agent")
      ->check(CLI::ExistingFile);
  app->add_option("--out", a->out, "folder for fleet.json and the score")->capture_default_str();
  app->add_option("--start-delay", a->start_delay_s, "seconds for discovery before the first batch")
      ->capture_default_str();
  app->add_option("--drain", a->drain_s, "after the last batch, wait this long for the acknowledgements [s]")
      ->capture_default_str();
  app->add_option("--progress", a->progress_s, "seconds between progress lines")->capture_default_str();
  app->add_option("--score", a->score_map,
                  "no playing: score this map file (ccm_server --save-map) against the recordings' ground truth");
  app->add_flag("--offline", a->offline,
                "no DDS: play the streams into a back-end in this process (ccm_replay's deterministic engine) and "
                "score it, the yardstick for a live run");
  app->add_option("--vocab", a->vocabulary, "vocabulary the server used (--score, --offline)");
  app->add_option("--theta", a->offline_server.redundancy.theta,
                  "--offline: redundancy removal's threshold (share of a keyframe's points seen by >= 3 others)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app->add_option("--revisit-ratio", a->offline_server.redundancy.revisit_distance_ratio,
                  "--offline: redundancy: a keyframe this close to one of an earlier pass (share of its scene "
                  "depth, 15 deg) leaves as its anchor (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  return rt::AddDdsOptions(app, &a->config, &a->session);
}

bool Resolve(const rt::DdsOptionsGiven& given, Args* a, std::string* error) {
  if (!a->config_path.empty()) {
    agent::AgentConfig from_file;
    if (!agent::LoadAgentConfig(a->config_path, &from_file, error)) return false;
    const agent::AgentConfig cli = a->config;
    a->config = from_file;
    rt::KeepGivenDdsOptions(given, cli, &a->config);
  }
  if (!a->config.security_dir.empty() && !a->config.insecure) {
    *error = "ccm_fleet plays many agent ids from one process and has one security_dir: run it with --insecure "
             "against a server without DDS-Security";
    return false;
  }
  if (a->team.speed <= 0 || a->team.stagger_s < 0 || a->start_delay_s < 0 || a->drain_s < 0 || a->progress_s <= 0) {
    *error = "--speed and --progress must be > 0, --stagger, --start-delay and --drain >= 0";
    return false;
  }
  if (std::string problem = a->config.Validate(); !problem.empty()) return *error = problem, false;
  // Every agent logs its link set-up at info: sixteen identical lines. The fleet's own
  // progress is printed, so its agents log warnings and errors unless asked for more.
  if (!*given.log && a->config_path.empty()) a->config.log_level = "warn";
  if (!rt::SetupLogging(a->config.log_level, error)) return false;
  return rt::ResolveSession(a->config, &a->session, error);
}

// Plays the team until every stream is played and acknowledged (or Ctrl-C / the drain
// period), printing progress; writes fleet.json. Exit code 0, or 3 if keyframes stayed
// unacknowledged.
int Play(const Args& a, fleet::Team* team) {
  std::string error;
  const auto start = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                            std::chrono::duration<double>(a.start_delay_s));
  if (!team->Connect(a.config, a.session, start, &error)) return Fail(error, 1);
  std::printf("fleet: %zu agents from %zu recording(s), %.0f s of wall time at %gx the recorded pace (+%.0f s for "
              "discovery)\n", team->size(), a.team.recordings.size(), team->duration_s(), a.team.speed, a.start_delay_s);
  auto next_progress = std::chrono::steady_clock::now();
  while (!g_stop && !team->Finished()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (std::chrono::steady_clock::now() >= next_progress) {
      std::printf("%s\n", team->ProgressLine().c_str());
      std::fflush(stdout);
      next_progress += std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(a.progress_s));
    }
  }
  const bool drained = team->Drain(std::chrono::milliseconds(static_cast<int64_t>(a.drain_s * 1000)));
  std::printf("%s\n", team->ProgressLine().c_str());
  const nlohmann::json summary = team->Summary();
  std::filesystem::create_directories(a.out);
  std::ofstream(a.out + "/fleet.json") << summary.dump(2) << "\n";
  std::printf("%s\n", summary["totals"].dump().c_str());
  if (!drained) spdlog::warn("fleet: keyframes still unacknowledged after {:.0f} s", a.drain_s);
  return drained ? 0 : 3;
}

std::shared_ptr<const Vocabulary> LoadVocabulary(const Args& a, std::string* error) {
  if (a.vocabulary.empty()) return *error = "no vocabulary: give --vocab FILE (the one the server used)", nullptr;
  auto loaded = LoadVocabularyFile(a.vocabulary, error);
  if (!loaded) return nullptr;
  return std::make_shared<const Vocabulary>(std::move(*loaded));
}

void Report(const report::RunResult& result, const ServerBackend& backend, const std::string& dir) {
  const report::RunEvaluation evaluation = report::EvaluateRun(result);
  report::PrintRunSummary(result, evaluation);
  std::string error;
  if (!report::WriteRunOutputs(dir, result, evaluation, backend.Snapshot(), &error)) {
    spdlog::error("{}", error);
    return;
  }
  std::printf("scored in %s (summary.json, map<k>_<agent>_keyframes.tum)\n", dir.c_str());
}

int Offline(const Args& a, const fleet::Team& team) {
  std::string error;
  auto vocab = LoadVocabulary(a, &error);
  if (!vocab) return Fail(error);
  ServerBackend backend(vocab, a.offline_server);
  std::printf("offline: %zu batches of %zu agents into one back-end\n", team.recording().batches.size(), team.size());
  const report::RunResult result = replay::PlayRecording(team.recording(), &backend, replay::PlayOptions{});
  Report(result, backend, a.out + "/offline");
  return 0;
}

int Score(const Args& a, const fleet::Team& team) {
  std::string error;
  auto vocab = LoadVocabulary(a, &error);
  if (!vocab) return Fail(error);
  auto backend = LoadBackend(a.score_map, vocab, ServerOptions{}, &error);
  if (!backend) return Fail(error, 1);
  report::RunResult result = team.ResultFromMaps(*backend);
  // The loaded back-end has not run: the live server's fusions and loops are in its events.
  for (const ServerEvent& e : result.events) {
    if (e.kind == ServerEvent::Kind::kFusion) ++result.stats.fusions;
    if (e.kind == ServerEvent::Kind::kLoop) ++result.stats.loops;
    if (e.kind == ServerEvent::Kind::kGlobalBa) ++result.stats.global_ba_applied;
  }
  Report(result, *backend, a.out + "/score");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  CLI::App app{"ccm_fleet: recorded agents as a team on the wire, against a real ccm_server"};
  const rt::DdsOptionsGiven given = AddOptions(&app, &a);
  CLI11_PARSE(app, argc, argv);
  rt::SetUpGlog(argv[0]);
  std::string error;
  if (!Resolve(given, &a, &error)) return Fail(error);
  if (a.offline && !a.score_map.empty()) return Fail("--offline and --score exclude each other");
  a.team.keep_batches = a.offline;
  auto team = fleet::Team::Load(a.team, &error);
  if (!team) return Fail(error);
  if (!a.score_map.empty()) return Score(a, *team);
  if (a.offline) return Offline(a, *team);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  return Play(a, team.get());
}
