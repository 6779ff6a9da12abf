// ccm_replay: offline collaborative SLAM of recorded multi-robot flights. Runs each agent's
// onboard VO and the server back-end in one process (the real system's code paths minus
// DDS), then writes every map that remains: each agent's keyframe trajectory per map (TUM),
// summary.json (maps with their agents, fusions and loops with times, place recognition,
// keyframe counts, timings, accuracy per map when ground truth is known), the maps (PLY) and
// a PNG top view with a panel per map. See docs/server.md.
#include <glog/logging.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <iostream>
#include <mutex>
#include <thread>

#include "agent_runtime/agent_config.h"
#include "slam_core/common/install_paths.h"
#include "server_runtime/map_view_server.h"
#include "slam_core/io/dataset.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"
#include "tools/replay/batch_recording.h"
#include "tools/replay/dataset_spec.h"
#include "server_runtime/run_report.h"
#include "slam_core/server/map_persistence.h"

#ifndef CCM_DEFAULT_VOCABULARY
#define CCM_DEFAULT_VOCABULARY ""
#endif

namespace {

struct Args {
  std::string sim;
  std::vector<int> sim_agents;
  std::vector<std::string> datasets;
  std::vector<std::string> ground_truth;  // one for all datasets, or one per dataset
  std::string format = "auto";
  // The installed copy first (install_paths.h), then the build tree's.
  std::string vocabulary = ccm::rt::FindDataFile(ccm::rt::kInstalledVocabulary, CCM_DEFAULT_VOCABULARY);
  std::string out = "replay-out";
  std::string save_map, load_map, record;
  std::string agent_config;  // ccm_agent YAML: its vo section, N, B, keyframe delay and sharing
  ccm::replay::ReplayOptions replay;
  bool no_sharing = false, no_redundancy = false, no_final_ba = false;
  ccm::server::MapViewServerOptions map_view;
  double http_linger_s = 0.0;
};

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

/// The replay's part of the map view's status: agent names and how far each input is.
class ReplayViewStatus {
 public:
  explicit ReplayViewStatus(const std::vector<ccm::replay::ReplayAgentInput>& inputs) {
    for (const auto& in : inputs) names_[in.id] = in.name;
  }
  void Update(const ccm::replay::ReplayProgress& p, bool finished) {
    std::lock_guard<std::mutex> lock(mutex_);
    progress_ = p;
    finished_ = finished;
  }
  nlohmann::json Json() const {
    std::lock_guard<std::mutex> lock(mutex_);
    nlohmann::json agents = nlohmann::json::object();
    for (const auto& [id, name] : names_) agents[std::to_string(id)] = {{"name", name}};
    return {{"source", "ccm_replay"}, {"agents", agents}, {"frames_done", progress_.frames_done},
            {"frames_total", progress_.frames_total}, {"finished", finished_}};
  }

 private:
  mutable std::mutex mutex_;  // leaf
  std::map<ccm::AgentId, std::string> names_;
  ccm::replay::ReplayProgress progress_;
  bool finished_ = false;
};

int Fail(const std::string& message, int code = 2) {
  std::cerr << "ccm_replay: error: " << message << "\n";
  return code;
}

bool OpenInputs(const Args& a, std::vector<ccm::replay::ReplayAgentInput>* inputs, std::string* error) {
  if (!a.sim.empty()) {
    const auto scenario = ccm::sim::LoadScenario(a.sim, error);
    if (!scenario) return false;
    std::shared_ptr<const ccm::sim::Simulation> sim(ccm::sim::Simulation::Create(*scenario, error));
    if (!sim) return false;
    std::vector<int> ids = a.sim_agents;
    if (ids.empty()) {
      for (int i = 0; i < sim->num_agents(); ++i) ids.push_back(i);
    }
    for (const int i : ids) {
      if (i < 0 || i >= sim->num_agents()) {
        *error = "scenario '" + a.sim + "' has " + std::to_string(sim->num_agents()) + " agents; agent " +
                 std::to_string(i) + " does not exist";
        return false;
      }
      inputs->push_back({sim->agent_name(i), static_cast<ccm::AgentId>(i + 1),
                         std::make_unique<ccm::sim::SimFrameSource>(sim, i)});
    }
  }
  if (a.ground_truth.size() > 1 && a.ground_truth.size() != a.datasets.size()) {
    *error = "--ground-truth: give one file for every --dataset, or one per --dataset (" +
             std::to_string(a.datasets.size()) + "), not " + std::to_string(a.ground_truth.size());
    return false;
  }
  for (size_t i = 0; i < a.datasets.size(); ++i) {
    const auto spec = ccm::replay::ParseDatasetSpec(a.datasets[i], error);
    if (!spec) return false;
    ccm::DatasetOptions options;
    options.path = spec->path;
    options.format = *ccm::ParseDatasetFormat(a.format);
    if (!a.ground_truth.empty()) options.ground_truth_path = a.ground_truth[a.ground_truth.size() == 1 ? 0 : i];
    ccm::IoStatus status;
    auto source = ccm::OpenDataset(options, &status);
    if (source && spec->range) source = ccm::LimitFrames(std::move(source), *spec->range, &status);
    if (!source) {
      *error = spec->range ? spec->path + ": " + status.message() : status.message();
      return false;
    }
    inputs->push_back({spec->name.empty() ? "agent" + std::to_string(inputs->size()) : spec->name,
                       static_cast<ccm::AgentId>(inputs->size() + 1), std::move(source)});
  }
  // Outputs are named after the agents: one folder given twice must not overwrite itself.
  std::vector<std::string> names;
  for (const auto& in : *inputs) names.push_back(in.name);
  ccm::replay::MakeNamesUnique(&names);
  for (size_t i = 0; i < inputs->size(); ++i) (*inputs)[i].name = names[i];
  if (inputs->empty()) *error = "nothing to replay: give --sim SCENARIO or --dataset DIR (repeat per agent)";
  return !inputs->empty();
}

/// Options a flag given on the command line wins over the --agent-config file for.
struct ExplicitFlags {
  CLI::Option* keyframe_delay = nullptr;
  CLI::Option* anchor_duplicates = nullptr;
};

ExplicitFlags AddOptions(CLI::App* app, Args* a) {
  ExplicitFlags flags;
  app->add_option("--sim", a->sim, "built-in scenario (hall3, disjoint2, repeated) or scenario YAML");
  app->add_option("--sim-agents", a->sim_agents, "scenario agent indices (default: all)")->delimiter(',');
  app->add_option("--dataset", a->datasets,
                 "dataset folder (EuRoC/TUM/KITTI layout), one per agent; repeat. DIR@FIRST-LAST takes "
                 "frames FIRST..LAST (0-based, inclusive; DIR@FIRST- to the end), so slices of one "
                 "sequence can be several agents");
  app->add_option("--ground-truth", a->ground_truth,
                 "ground-truth file of the datasets in the reader's format (KITTI: poses file; EuRoC: "
                 "data.csv; TUM: groundtruth.txt) when not at its usual place: once for every --dataset, "
                 "or once per --dataset in order")->check(CLI::ExistingFile);
  app->add_option("--format", a->format, "dataset format: auto, euroc, tum, kitti")->capture_default_str();
  app->add_option("--vocab", a->vocabulary, "bag-of-words vocabulary (ccm_vocab)")->capture_default_str();
  app->add_option("--out", a->out, "output folder")->capture_default_str();
  app->add_option("--max-frames", a->replay.max_frames, "frames per agent (-1: all)")->capture_default_str();
  app->add_option("--send-period", a->replay.send_period_s, "agent -> server batch period, data time [s]")
      ->capture_default_str();
  app->add_flag("--threaded", a->replay.threaded, "agents and server stages on their own threads (not deterministic)");
  app->add_flag("--no-sharing", a->no_sharing, "do not send the server's neighbourhood back to the agents");
  flags.keyframe_delay = app->add_option("--keyframe-delay", a->replay.new_keyframe_delay_s,
                 "a new keyframe is sent once this old, data time [s] (as ccm_agent)")->capture_default_str();
  flags.anchor_duplicates = app->add_option("--anchor-duplicates", a->replay.anchor_duplicates.distance_ratio,
                 "near-duplicate keyframes (this share of the scene depth) leave as pose anchors only; "
                 "0: every keyframe in full (as ccm_agent's anchor_duplicate_distance_ratio)")->capture_default_str();
  app->add_option("--agent-config", a->agent_config,
                 "ccm_agent YAML for every agent: its vo section, max_keyframes, buffer_keyframes, "
                 "new_keyframe_delay_s and map_sharing (the flags above win)")->check(CLI::ExistingFile);
  app->add_flag("--no-redundancy", a->no_redundancy, "keep every keyframe (no redundancy removal)");
  app->add_option("--theta", a->replay.server.redundancy.theta, "redundancy threshold")->capture_default_str();
  app->add_option("--revisit-ratio", a->replay.server.redundancy.revisit_distance_ratio,
                  "redundancy: a keyframe this close to one of an earlier pass (share of its scene "
                  "depth, 15 deg) leaves as its anchor (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  app->add_option("--share-own-after", a->replay.server.share_own_keyframes_after_s,
                 "map sharing also sends an agent its own keyframes this many seconds older than its reference "
                 "(0: other agents' only; experimental)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app->add_option("--ba-max-free", a->replay.server.optimization.global_ba_max_free_keyframes,
                 "a loop or fusion in a map above this many keyframes gets a global BA of its region only (0: whole map)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app->add_option("--ba-min-parallax", a->replay.server.optimization.global_ba_min_parallax_deg,
                  "points seen under less parallax [deg] are held in the server's global BA (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 89.9));
  app->add_flag("--ba-inverse-depth", a->replay.server.optimization.global_ba_low_parallax_inverse_depth,
                "points under --ba-min-parallax move as inverse depths from their reference keyframe instead of being held");
  app->add_option("--weld-ratio", a->replay.server.mapping.overlap_weld_depth_ratio,
                  "after a fusion, weld the whole overlap: keyframes closer than this share of the scene depth "
                  "(0: only the verified pair's neighbourhood)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  app->add_option("--cut-at", a->replay.link_cut_at_s,
                  "cut every agent's link this long after its first frame, data time [s]: its batches are held "
                  "and arrive in one burst when the link returns, no acks or map sharing meanwhile (-1: no cut)")
      ->capture_default_str();
  app->add_option("--cut-s", a->replay.link_cut_s, "length of the --cut-at outage, data time [s]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app->add_option("--cut-points-late", a->replay.link_cut_points_late_s,
                  "with --cut-at: the burst's points arrive this long after their keyframes, which reach the server "
                  "flagged as released without their points (as after a live outage) [s]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app->add_flag("--no-final-ba", a->no_final_ba,
                "skip the end-of-run work: the sweep of repeated passes and the global BA of every map");
  app->add_option("--load-map", a->load_map, "start from a saved map stack");
  app->add_option("--save-map", a->save_map, "save the map stack at the end");
  app->add_option("--record", a->record, "write every agent batch to this file (replayable without the VO)");
  ccm::server::AddMapViewOptions(app, &a->map_view);
  app->add_option("--http-linger", a->http_linger_s,
                 "with --http: keep serving the map view this long after the replay (-1: until Ctrl-C) [s]");
  return flags;
}

/// Applies --agent-config and the flags to the replay options; an empty string when all is valid.
std::string FinishArgs(const ExplicitFlags& flags, Args* a) {
  a->replay.map_sharing = !a->no_sharing;
  if (!a->agent_config.empty()) {
    // Replay what a deployed agent would do with this file (tuning without DDS).
    ccm::agent::AgentConfig config;
    std::string config_error;
    if (!ccm::agent::LoadAgentConfig(a->agent_config, &config, &config_error)) return config_error;
    a->replay.vo = config.EffectiveVo();
    if (flags.keyframe_delay->count() == 0) a->replay.new_keyframe_delay_s = config.new_keyframe_delay_s;
    const double ratio = a->replay.anchor_duplicates.distance_ratio;
    a->replay.anchor_duplicates = config.anchor_duplicates;
    if (flags.anchor_duplicates->count() > 0) a->replay.anchor_duplicates.distance_ratio = ratio;
    a->replay.map_sharing = config.map_sharing && !a->no_sharing;
  }
  a->replay.server.redundancy.enabled = !a->no_redundancy;
  a->replay.final_global_ba = !a->no_final_ba;
  if (!ccm::ParseDatasetFormat(a->format)) return "--format must be auto, euroc, tum or kitti";
  if (a->http_linger_s != 0.0 && !a->map_view.enabled()) return "--http-linger needs --http PORT";
  if (const std::string e = a->map_view.Validate(); a->map_view.port != -1 && !e.empty()) return e;
  if (const std::string e = a->replay.Validate(); !e.empty()) return e;
  if (a->vocabulary.empty()) return "no vocabulary: give --vocab FILE (train one with ccm_vocab train)";
  return "";
}

std::unique_ptr<ccm::ServerBackend> MakeBackend(const Args& a, std::shared_ptr<const ccm::Vocabulary> vocab,
                                                 std::string* error) {
  if (a.load_map.empty()) return std::make_unique<ccm::ServerBackend>(std::move(vocab), a.replay.BackendOptions());
  return ccm::LoadBackend(a.load_map, std::move(vocab), a.replay.BackendOptions(), error);
}

bool WriteOutputs(const Args& a, const ccm::report::RunResult& result, const ccm::ServerBackend& backend,
                  ccm::replay::Recording* recording, std::string* error) {
  const auto evaluation = ccm::report::EvaluateRun(result);
  ccm::report::PrintRunSummary(result, evaluation);
  if (!ccm::report::WriteRunOutputs(a.out, result, evaluation, backend.Snapshot(), error)) return false;
  if (!a.save_map.empty() && !ccm::SaveBackend(backend, a.save_map, error)) return false;
  if (!a.record.empty()) {
    ccm::replay::RecordAgents(result, recording);
    if (!ccm::replay::SaveRecording(*recording, a.record, error)) return false;
  }
  std::printf("outputs in %s (summary.json, map<k>_<agent>_keyframes.tum per map, <agent>_keyframes.tum of the "
              "largest map, map.ply, map_top.png)\n", a.out.c_str());
  std::fflush(stdout);
  return true;
}

/// --http-linger: the map view keeps serving the finished replay (until Ctrl-C when negative).
void LingerForMapView(const Args& a, const ccm::server::MapViewServer& view, const ccm::report::RunResult& result,
                      ReplayViewStatus* view_status) {
  ccm::replay::ReplayProgress done;
  for (const auto& r : result.agents) done.frames_done += r.frames;
  done.frames_total = done.frames_done;
  view_status->Update(done, true);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  if (a.http_linger_s < 0) {
    std::printf("map view stays on %s (until Ctrl-C)\n", view.url().c_str());
  } else {
    std::printf("map view stays on %s (%.0f s)\n", view.url().c_str(), a.http_linger_s);
  }
  std::fflush(stdout);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(a.http_linger_s);
  while (!g_stop && (a.http_linger_s < 0 || std::chrono::steady_clock::now() < until)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

}  // namespace

int main(int argc, char** argv) {
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = 2;  // Ceres' glog warnings would flood the terminal
  Args a;
  CLI::App app{"ccm_replay: several agents' VO + the server back-end in one process (no DDS)"};
  const ExplicitFlags flags = AddOptions(&app, &a);
  CLI11_PARSE(app, argc, argv);
  if (const std::string e = FinishArgs(flags, &a); !e.empty()) return Fail(e);
  std::string error;
  auto loaded = ccm::LoadVocabularyFile(a.vocabulary, &error);
  if (!loaded) return Fail(error);
  auto vocab = std::make_shared<const ccm::Vocabulary>(std::move(*loaded));
  a.replay.agent_vocabulary = vocab;  // agents relocalize with the same vocabulary

  std::vector<ccm::replay::ReplayAgentInput> inputs;
  if (!OpenInputs(a, &inputs, &error)) return Fail(error);
  std::unique_ptr<ccm::ServerBackend> backend = MakeBackend(a, vocab, &error);
  if (!backend) return Fail(error);
  spdlog::info("replaying {} agents ({}), vocabulary {} words", inputs.size(), a.replay.threaded ? "threaded" : "deterministic",
               vocab->num_words());
  ReplayViewStatus view_status(inputs);
  std::unique_ptr<ccm::server::MapViewServer> view;
  if (a.map_view.enabled()) {
    view = ccm::server::MapViewServer::Start(a.map_view, backend.get(), [&view_status] { return view_status.Json(); },
                                             &error);
    if (!view) return Fail(error);
    // Tests and scripts read this line for the port (--http 0 picks a free one).
    std::printf("map view on %s\n", view->url().c_str());
    std::fflush(stdout);
  }
  ccm::replay::Recording recording;
  if (!a.record.empty()) a.replay.on_batch = [&recording](const ccm::AgentBatch& b) { recording.batches.push_back(b); };
  const auto result = ccm::replay::RunReplay(std::move(inputs), a.replay, backend.get(), [&view_status](const auto& p) {
    view_status.Update(p, false);
    size_t kfs = 0;
    for (const auto& m : p.maps) kfs += m.keyframes;
    spdlog::info("{:5.0f} s  frames {}/{}  maps {}  keyframes {}  fusions {}  loops {}", p.elapsed_s, p.frames_done,
                 p.frames_total, p.maps.size(), kfs, p.fusions, p.loops);
  });
  if (!result.error.empty()) return Fail(result.error, 1);
  if (!WriteOutputs(a, result, *backend, &recording, &error)) return Fail(error, 1);
  if (view && a.http_linger_s != 0.0) LingerForMapView(a, *view, result, &view_status);
  if (view) view->Stop();
  return 0;
}
