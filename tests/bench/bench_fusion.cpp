// bench_fusion: collaboration over a distribution of generated scenes (docs/server.md,
// "Fusion benchmark"). Each seed makes a scene (tests/sim/scene_generator.h); its agents fly
// through the real VO and server back-end (ccm_replay's engine, deterministic), and the run
// is scored against the simulator's ground truth (fusion_scoring.h). Prints one block per
// scene as it finishes, then a table per scene and per agent, then the totals against the
// goals. Seeds 1-20 are the tuning set, 1001-1040 the held-out set (report only).
//   bench_fusion --set held-out --jobs 2 --out bench-out
//   bench_fusion --seeds 3,7,12-14 --max-agents 4
//   bench_fusion --set tune --record recs && bench_fusion --set tune --play recs   # server only
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include <CLI/CLI.hpp>
#include <glog/logging.h>
#include <nlohmann/json.hpp>

#include "slam_core/place_recognition/vocabulary_io.h"
#include "tests/bench/fusion_recall.h"
#include "tests/bench/fusion_report.h"
#include "tests/bench/fusion_scoring.h"
#include "tools/replay/batch_recording.h"
#include "tests/sim/scene_generator.h"
#include "tests/sim/sim_frame_source.h"

namespace {

using ccm::bench::SceneResult;

bool ParseSeeds(const std::string& text, std::vector<std::uint64_t>* out, std::string* error) {
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      const size_t dash = item.find('-');
      const std::uint64_t lo = std::stoull(item.substr(0, dash));
      const std::uint64_t hi = dash == std::string::npos ? lo : std::stoull(item.substr(dash + 1));
      if (hi < lo || hi - lo > 100000) throw std::out_of_range(item);
      for (std::uint64_t s = lo; s <= hi; ++s) out->push_back(s);
    } catch (const std::exception&) {
      *error = "--seeds: '" + item + "' is not a seed or a range like 1001-1030";
      return false;
    }
  }
  return !out->empty();
}

// Where a scene's recording lives (--record / --play).
std::string RecordingPath(const std::string& dir, std::uint64_t seed) {
  return dir + "/gen-" + std::to_string(seed) + ".ccmrec";
}

SceneResult RunScene(std::uint64_t seed, const ccm::sim::SceneGeneratorOptions& gen,
                     const ccm::replay::ReplayOptions& base, const std::shared_ptr<const ccm::Vocabulary>& vocab,
                     const std::string& record_dir, const std::string& play_dir, bool recall) {
  const auto t0 = std::chrono::steady_clock::now();
  SceneResult out;
  out.scene = ccm::sim::GenerateScene(seed, gen);
  std::string error;
  const auto scenario = ccm::sim::ParseScenarioYaml(out.scene.yaml, "gen:" + std::to_string(seed), &error);
  std::shared_ptr<const ccm::sim::Simulation> sim;
  if (scenario) sim.reset(ccm::sim::Simulation::Create(*scenario, &error).release());
  if (!sim) {
    out.error = error;
    return out;
  }
  const auto truth = ccm::sim::OverlapTruth::Compute(*sim);
  // --recall: every map-matching query traced, every keyframe's stamp kept.
  std::mutex trace_mutex;  // leaf: traces (the place-recognition thread appends)
  std::vector<ccm::FusionQueryTrace> traces;
  std::map<ccm::KeyframeId, int64_t> stamps;
  ccm::ServerOptions server_options = base.BackendOptions();
  if (recall) {
    server_options.place.fusion_trace = [&](const ccm::FusionQueryTrace& t) {
      std::lock_guard<std::mutex> lock(trace_mutex);
      traces.push_back(t);
    };
  }
  ccm::ServerBackend backend(vocab, server_options);
  ccm::report::RunResult result;
  if (!play_dir.empty()) {
    // The agents' batches as recorded: only the server runs again (server-side tuning).
    const auto recording = ccm::replay::LoadRecording(RecordingPath(play_dir, seed), &error);
    if (!recording) {
      out.error = error;
      return out;
    }
    ccm::replay::PlayOptions play;
    play.final_global_ba = base.final_global_ba;
    result = ccm::replay::PlayRecording(*recording, &backend, play);
    for (const ccm::AgentBatch& b : recording->batches) {
      for (const ccm::KeyframeData& k : b.keyframes) stamps[k.id] = k.stamp_ns;
    }
  } else {
    std::vector<ccm::replay::ReplayAgentInput> inputs;
    for (int a = 0; a < sim->num_agents(); ++a) {
      inputs.push_back({sim->agent_name(a), static_cast<ccm::AgentId>(a + 1),
                        std::make_unique<ccm::sim::SimFrameSource>(sim, a)});
    }
    ccm::replay::ReplayOptions options = base;
    ccm::replay::Recording recording;
    options.on_batch = [&](const ccm::AgentBatch& b) {
      for (const ccm::KeyframeData& k : b.keyframes) stamps[k.id] = k.stamp_ns;
      if (!record_dir.empty()) recording.batches.push_back(b);
    };
    result = ccm::replay::RunReplay(std::move(inputs), options, &backend);
    if (!record_dir.empty()) {
      ccm::replay::RecordAgents(result, &recording);
      if (!ccm::replay::SaveRecording(recording, RecordingPath(record_dir, seed), &error)) out.error = error;
    }
  }
  if (!result.error.empty()) {
    out.error = result.error;
    return out;
  }
  out.score = ccm::bench::ScoreScene(*sim, truth, result);
  if (recall) {
    std::vector<ccm::AgentId> ids;
    for (const auto& a : result.agents) ids.push_back(a.id);
    std::lock_guard<std::mutex> lock(trace_mutex);
    out.missed = ccm::bench::DiagnoseMissedPairs(*sim, truth, out.score, traces, stamps, ids,
                                                 server_options.place.fusion_min_common_ratio);
  }
  out.frames = 0;
  for (const auto& a : result.agents) out.frames += a.frames;
  out.place_recognition_ms = result.stats.place.queries
                                 ? result.stats.place.total_query_ms / static_cast<double>(result.stats.place.queries)
                                 : 0.0;
  out.place = result.stats.place;
  for (const auto& [kfs, s] : result.stats.global_ba_seconds) {
    ++out.global_bas;
    out.global_ba_total_s += s;
    if (s > out.global_ba_max_s) out.global_ba_max_s = s, out.global_ba_max_keyframes = kfs;
  }
  for (const ccm::ServerEvent& e : result.events) {
    if (e.kind == ccm::ServerEvent::Kind::kGlobalBa) out.global_ba_details.push_back(e.detail);
  }
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = 2;
  CLI::App app{"bench_fusion: map fusion, loops and VO over generated multi-agent scenes, scored on ground truth"};
  std::string seeds_text, set, out_dir, record_dir, play_dir, vocab_path = CCM_DEFAULT_VOCABULARY;
  int jobs = 1;
  bool no_sharing = false, events = false, recall = false;
  ccm::sim::SceneGeneratorOptions gen;
  ccm::replay::ReplayOptions replay;
  app.add_option("--seeds", seeds_text, "seeds, e.g. 1-20 or 3,7,1001-1005");
  app.add_option("--set", set, "tune (seeds 1-20) or held-out (seeds 1001-1040)")->check(CLI::IsMember({"tune", "held-out"}));
  app.add_option("--jobs", jobs, "scenes replayed at once (one thread each)")->capture_default_str()->check(CLI::Range(1, 16));
  app.add_option("--min-agents", gen.min_agents, "at least this many agents per scene")->capture_default_str();
  app.add_option("--max-agents", gen.max_agents, "at most this many agents per scene (up to 16; more than 8 makes a "
                                                 "team-scale hall or yard of 3-4 rows)")
      ->capture_default_str();
  app.add_option("--min-seconds", gen.min_duration_s, "shortest flight [s]")->capture_default_str();
  app.add_option("--max-seconds", gen.max_duration_s, "longest flight [s]")->capture_default_str();
  app.add_option("--vocab", vocab_path, "bag-of-words vocabulary")->capture_default_str();
  app.add_option("--out", out_dir, "folder for results.jsonl (one line per scene) and report.md");
  app.add_flag("--no-sharing", no_sharing, "agents get no map data back from the server");
  bool no_final_ba = false;
  app.add_flag("--no-final-ba", no_final_ba,
               "score the maps as a live server holds them: without the end-of-run global BA and sweep");
  app.add_flag("--events", events, "print every fusion and loop with its ground-truth check");
  app.add_flag("--recall", recall,
               "for each overlapping pair that never fused: were the right keyframes retrieved, and where did "
               "their verification stop (ground truth)");
  app.add_option("--fusion-common-ratio", replay.server.place.fusion_min_common_ratio,
                 "place recognition: map-matching keyframes must share this share of the best one's words")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--seed-inliers", replay.server.place.verification.min_seed_inliers,
                 "place recognition: inliers the first Sim(3) RANSAC needs (the refined one needs 20)")
      ->capture_default_str()
      ->check(CLI::Range(3, 100));
  app.add_option("--theta", replay.server.redundancy.theta,
                 "redundancy removal: a keyframe goes when this share of its points is seen by >= 3 others")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--revisit-ratio", replay.server.redundancy.revisit_distance_ratio,
                 "redundancy: a keyframe this close to one of an earlier pass (share of its scene "
                 "depth, 15 deg) leaves as its anchor (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  app.add_option("--weld-ratio", replay.server.mapping.overlap_weld_depth_ratio,
                 "after a fusion, weld the whole overlap: keyframes closer than this share of the scene depth "
                 "(0: only the verified pair's neighbourhood; 0.5 tried)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--share-own-after", replay.server.share_own_keyframes_after_s,
                 "map sharing also sends an agent its own keyframes this many seconds older than its reference "
                 "(0: other agents' only)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--record", record_dir, "keep every scene's agent batches in this folder (gen-SEED.ccmrec)");
  app.add_option("--play", play_dir, "replay the batches recorded there instead of flying the VO (server only)");
  app.add_option("--candidate-window", replay.server.place.candidate_window,
                 "place recognition: covisible keyframes verified with each candidate (0: the candidate alone)")
      ->capture_default_str()
      ->check(CLI::Range(0, 20));
  app.add_option("--init-motion-gap", replay.vo.init_min_motion_cost_gap,
                 "VO start: the two-view motion must beat every rival >= 30 deg away by this cost (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  std::string kf_reference = "last";
  app.add_option("--kf-reference", kf_reference, "VO keyframe rule's reference: last, most_covisible or either")
      ->capture_default_str()
      ->check([&](const std::string& text) {
        return ccm::ParseKeyframeReference(text, &replay.vo.kf_reference) ? "" : "must be last, most_covisible or either";
      });
  app.add_option("--kf-inlier-drop", replay.vo.keyframe.inlier_drop_ratio,
                 "VO keyframe rule: a keyframe below this share of the last keyframe's inliers (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  app.add_option("--kf-turn", replay.vo.keyframe.turn_fov_share,
                 "VO keyframe rule: a keyframe at once after turning this share of the field of view (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--min-baseline-depth", replay.vo.min_baseline_depth_ratio,
                 "VO: keyframe pairs new points come from need this baseline over the neighbour's median depth")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  app.add_option("--min-parallax", replay.vo.min_triangulation_parallax_deg, "VO: ray angle new points need [deg]")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 10.0));
  std::string ba_solver = ccm::opt::BaLinearSolverName(replay.server.optimization.global_ba_solver);
  app.add_option("--ba-min-parallax", replay.server.optimization.global_ba_min_parallax_deg,
                 "points seen under less parallax [deg] are held in the server's global BA (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 89.9));
  app.add_flag("--ba-inverse-depth", replay.server.optimization.global_ba_low_parallax_inverse_depth,
               "points under --ba-min-parallax move as inverse depths from their reference keyframe instead of being held");
  app.add_option("--ba-max-free", replay.server.optimization.global_ba_max_free_keyframes,
                 "global BA after a loop or fusion in a map above this many keyframes: only the region around it (0: whole)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--ba-solver", ba_solver, "linear solver of the server's global BA (auto, sparse, iterative, dense)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (!ccm::opt::ParseBaLinearSolver(ba_solver, &replay.server.optimization.global_ba_solver)) {
    std::fprintf(stderr, "bench_fusion: error: unknown --ba-solver %s\n", ba_solver.c_str());
    return 2;
  }

  std::vector<std::uint64_t> seeds;
  std::string error;
  if (set == "tune") seeds_text = "1-20";
  if (set == "held-out") seeds_text = "1001-1040";
  if (seeds_text.empty()) {
    std::fprintf(stderr, "bench_fusion: error: give --seeds or --set\n");
    return 2;
  }
  if (!ParseSeeds(seeds_text, &seeds, &error) || !(error = gen.Validate()).empty()) {
    std::fprintf(stderr, "bench_fusion: error: %s\n", error.c_str());
    return 2;
  }
  auto loaded = ccm::LoadVocabularyFile(vocab_path, &error);
  if (!loaded) {
    std::fprintf(stderr, "bench_fusion: error: %s\n", error.c_str());
    return 2;
  }
  const auto vocab = std::make_shared<const ccm::Vocabulary>(std::move(*loaded));
  replay.agent_vocabulary = vocab;
  replay.map_sharing = !no_sharing;
  replay.final_global_ba = !no_final_ba;
  replay.progress_period_s = 1e9;
  if (!record_dir.empty()) std::filesystem::create_directories(record_dir);
  std::ofstream jsonl;
  if (!out_dir.empty()) {
    std::filesystem::create_directories(out_dir);
    jsonl.open(out_dir + "/results.jsonl", std::ios::app);
  }
  std::printf("bench_fusion: %zu scenes, %d job(s), vocabulary %s (%zu words), map sharing %s\n", seeds.size(), jobs,
              vocab_path.c_str(), vocab->num_words(), no_sharing ? "off" : "on");
  std::fflush(stdout);

  std::vector<SceneResult> results(seeds.size());
  std::atomic<size_t> next{0};
  std::mutex print_mutex;  // leaf: printing and the jsonl file
  std::vector<std::thread> workers;
  for (int j = 0; j < jobs; ++j) {
    workers.emplace_back([&] {
      for (size_t i; (i = next++) < seeds.size();) {
        results[i] = RunScene(seeds[i], gen, replay, vocab, record_dir, play_dir, recall);
        std::lock_guard<std::mutex> lock(print_mutex);
        std::fputs(ccm::bench::SceneBlock(results[i], events).c_str(), stdout);
        std::fflush(stdout);
        if (jsonl.is_open()) jsonl << ccm::bench::SceneJson(results[i]).dump() << "\n" << std::flush;
      }
    });
  }
  for (auto& w : workers) w.join();
  const std::string report = ccm::bench::Report(results);
  std::fputs(report.c_str(), stdout);
  if (!out_dir.empty()) std::ofstream(out_dir + "/report.md") << report;
  return 0;
}
