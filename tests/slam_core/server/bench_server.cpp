// Benchmark (not a test) of the server back-end on recorded agent streams (ccm_replay
// --record, or the hall3 recording ServerScenario.Hall3 leaves in the build tree):
//  1. registration + server mapping ms per keyframe, place recognition ms per keyframe;
//  2. global BA seconds vs keyframes (--ba-sizes; copies of the team are added to reach the largest);
//  3. how many agents' streams the server keeps up with: N agents (copies of the recorded
//     team with their own ids, each starting 2 s after the previous) are played at their
//     recorded rate into the threaded back-end; it keeps up if the backlog stays bounded and
//     the queues drain within a few seconds after the last batch.
// Usage: bench_server [--recording FILE] [--agents 3,6,8,10,12] [--speed 1] [--skip-ba]
//        [--ba-sizes 100,...,2000] [--ba-solver auto|sparse|iterative|dense] [--ba-threads 2]
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <thread>

#include "server_runtime/backend_runner.h"
#include "slam_core/eval/metrics.h"
#include "slam_core/server/global_ba.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "tools/replay/batch_recording.h"

namespace {

using namespace ccm;
using Clock = std::chrono::steady_clock;

double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }


template <typename IdT>
IdT Remap(IdT id, int group, int team) {
  if (!id.valid()) return id;
  return IdT::Make(static_cast<AgentId>(id.agent() + group * team), id.counter());
}

// Copy `group` of the recorded team: every id moves to agent + group * team.
AgentBatch CloneBatch(const AgentBatch& b, int group, int team) {
  AgentBatch c = b;
  c.agent = static_cast<AgentId>(b.agent + group * team);
  c.segment = Remap(b.segment, group, team);
  c.reference_kf = Remap(b.reference_kf, group, team);
  for (auto& k : c.keyframes) {
    k.id = Remap(k.id, group, team), k.segment = Remap(k.segment, group, team);
    k.predecessor = Remap(k.predecessor, group, team), k.parent = Remap(k.parent, group, team);
    for (auto& l : k.point_links) l.second = Remap(l.second, group, team);
  }
  for (auto& m : c.map_points) {
    m.id = Remap(m.id, group, team), m.segment = Remap(m.segment, group, team);
    m.reference_kf = Remap(m.reference_kf, group, team);
    for (auto& o : m.observations) o.first = Remap(o.first, group, team);
  }
  for (auto& u : c.keyframe_updates) {
    u.id = Remap(u.id, group, team), u.segment = Remap(u.segment, group, team);
    u.predecessor = Remap(u.predecessor, group, team), u.parent = Remap(u.parent, group, team);
  }
  for (auto& u : c.map_point_updates) u.id = Remap(u.id, group, team), u.reference_kf = Remap(u.reference_kf, group, team);
  return c;
}

// The first `agents` agents' batches (copies of the team as needed), in data-time order,
// each copy's agent k delayed by 2 s * k.
std::vector<std::pair<int64_t, AgentBatch>> Schedule(const replay::Recording& rec, int agents) {
  const int team = static_cast<int>(rec.agents.size());
  int64_t t0 = INT64_MAX;
  for (const auto& b : rec.batches) t0 = std::min(t0, b.stamp_ns);
  std::vector<std::pair<int64_t, AgentBatch>> out;
  for (int k = 0; k < agents; ++k) {
    const int group = k / team;
    const AgentId original = rec.agents[k % team].id;
    for (const auto& b : rec.batches) {
      if (b.agent != original) continue;
      out.emplace_back(b.stamp_ns - t0 + static_cast<int64_t>(k) * 2'000'000'000, CloneBatch(b, group, team));
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

void RegistrationTimes(const replay::Recording& rec, std::shared_ptr<const Vocabulary> vocab) {
  ServerBackend backend(vocab, ServerOptions{});
  const double cpu0 = CpuSeconds();
  const auto r = replay::PlayRecording(rec, &backend, {});
  const double cpu = CpuSeconds() - cpu0;
  std::vector<double> ms;
  int64_t kfs = 0, local_bas = 0;
  double reg_ms = 0, fusion_ms = 0, ba_ms = 0;
  for (const auto& [a, c] : r.stats.agents) {
    ms.insert(ms.end(), c.keyframe_ms.begin(), c.keyframe_ms.end());
    kfs += c.keyframes_registered;
    reg_ms += c.registration_ms, fusion_ms += c.fusion_ms, ba_ms += c.local_ba_ms, local_bas += c.local_bas;
  }
  double ba_s = 0;
  for (const auto& [n, s] : r.stats.global_ba_seconds) ba_s += s;
  std::printf("\n## 1. Per keyframe (%lld keyframes, %zu agents, one thread)\n\n", static_cast<long long>(kfs),
              rec.agents.size());
  std::printf("| stage | median | p95 | mean |\n|---|---|---|---|\n");
  std::printf("| registration + server mapping [ms] | %.1f | %.1f | %.1f |\n", Percentile(ms, 0.5), Percentile(ms, 0.95),
              ComputeStats(ms).mean);
  std::printf("| of which registration (placement, refinement, points, updates) [ms] | - | - | %.1f |\n", reg_ms / kfs);
  std::printf("| of which covisibility + duplicate-point fusion [ms] | - | - | %.1f |\n", fusion_ms / kfs);
  std::printf("| of which local BA (%lld of %lld keyframes) [ms] | - | - | %.1f |\n", static_cast<long long>(local_bas),
              static_cast<long long>(kfs), ba_ms / kfs);
  std::printf("| place recognition (query + verification) [ms] | - | - | %.1f |\n",
              r.stats.place.total_query_ms / std::max<int64_t>(1, r.stats.place.queries));
  std::printf("| global BA (%lld runs) [s] | - | - | %.2f |\n", static_cast<long long>(r.stats.global_ba_applied),
              ba_s / std::max<int64_t>(1, r.stats.global_ba_applied));
  std::printf("| everything, CPU per keyframe [ms] | - | - | %.1f |\n", 1000.0 * cpu / std::max<int64_t>(1, kfs));
  std::printf("fusions %lld, loops %lld, wall %.1f s\n", static_cast<long long>(r.stats.fusions),
              static_cast<long long>(r.stats.loops), r.wall_s);
}

void GlobalBaTimes(const replay::Recording& rec, std::shared_ptr<const Vocabulary> vocab,
                   const std::vector<size_t>& sizes, GlobalBaOptions options,
                   const std::vector<opt::BaLinearSolver>& solvers, const std::vector<int>& regions,
                   size_t map_keyframes) {
  // Copies of the team, no keyframe removal, until the map has the largest size asked for
  // (hall3's recording: ~550 keyframes per copy).
  ServerOptions o;
  o.redundancy.enabled = false;
  o.mapping.duplicate_distance_ratio = 0.0;
  o.optimization.global_ba_after_loop = o.optimization.global_ba_after_fusion = false;  // timed below
  ServerBackend backend(vocab, o);
  size_t recorded_kfs = 0;  // full ones (anchors do not enter a BA)
  for (const auto& b : rec.batches) {
    for (const auto& k : b.keyframes) recorded_kfs += k.anchor_only ? 0 : 1;
  }
  const size_t largest = std::max(map_keyframes, sizes.empty() ? 0 : *std::max_element(sizes.begin(), sizes.end()));
  const int copies = 1 + static_cast<int>(1.5 * largest / std::max<size_t>(1, recorded_kfs));
  for (const auto& [t, b] : Schedule(rec, copies * static_cast<int>(rec.agents.size()))) {
    backend.Submit(b);
    backend.ProcessAllQueued();
  }
  std::shared_ptr<const ServerMap> biggest;
  for (const auto& m : backend.Snapshot().maps) {
    if (!biggest || m->map().num_keyframes() > biggest->map().num_keyframes()) biggest = m;
  }
  auto kfs = biggest->map().keyframes();
  std::sort(kfs.begin(), kfs.end(), [](const auto& a, const auto& b) { return a->stamp_ns() < b->stamp_ns(); });
  std::printf("\n## 2. Global BA vs keyframes (map grown in time order; the server's global BA: %d robust + %d "
              "plain iterations, %d threads; gross outliers left out)\n\n",
              options.iterations, options.iterations, options.threads);
  std::printf("| keyframes | points | observations | solver | wall [s] | CPU [s] | iterations (rejected) | RMSE before -> after [px] | inlier RMSE after [px] | cost before -> after |\n|---|---|---|---|---|---|---|---|---|---|\n");
  for (const size_t n : sizes) {
    if (n > kfs.size()) {
      std::printf("| %zu | (map has only %zu keyframes) | | | |\n", n, kfs.size());
      continue;
    }
    opt::BundleProblem p;
    std::unordered_map<KeyframeId, int> index;
    for (size_t i = 0; i < n; ++i) {
      if (p.cameras.empty()) p.cameras.push_back(kfs[i]->camera_ptr());
      index.emplace(kfs[i]->id(), static_cast<int>(i));
      p.poses.push_back({kfs[i]->id().packed(), kfs[i]->world_from_cam(), i == 0, 0});
    }
    for (const auto& mp : biggest->map().map_points()) {
      std::vector<opt::Observation> obs;
      for (const auto& [kf, idx] : mp->observations()) {
        const auto it = index.find(kf);
        if (it == index.end()) continue;
        const Keypoint& k = kfs[it->second]->features().keypoints[idx];
        obs.push_back({it->second, static_cast<int>(p.points.size()), Eigen::Vector2d(k.u, k.v),
                       kfs[it->second]->pyramid().scale[k.level]});
      }
      if (static_cast<int>(obs.size()) < options.min_observations) continue;
      bool low_parallax = false;  // held or anchored as the server's BA does
      p.points.push_back(GlobalBaPointBlock(*mp, obs, kfs, options, &low_parallax));
      p.observations.insert(p.observations.end(), obs.begin(), obs.end());
    }
    DropGrossOutliers(&p, options);
    const double rmse0 = opt::ReprojectionRmsePx(p);
    for (const opt::BaLinearSolver solver : solvers) {
      opt::BundleProblem q = p;
      options.linear_solver = solver;
      const auto w0 = Clock::now();
      const double c0 = CpuSeconds();
      const auto s = opt::BundleAdjust(&q, GlobalBaSolverOptions(options, nullptr));
      std::printf("| %zu | %zu | %zu | %s | %.2f | %.2f | %d (%d) | %.3f -> %.3f | %.3f | %.4g -> %.4g |%s\n", n, q.points.size(),
                  q.observations.size(), opt::BaLinearSolverName(solver), std::chrono::duration<double>(Clock::now() - w0).count(),
                  CpuSeconds() - c0, s.iterations, s.rejected_steps, rmse0, opt::ReprojectionRmsePx(q),
                  opt::ReprojectionRmsePx(q, &s.inlier), s.initial_cost, s.final_cost,
                  s.usable ? "" : (" failed: " + s.message).c_str());
      std::fflush(stdout);
    }
  }
  // What a loop or fusion in a big map gets (GlobalBaOptions::max_free_keyframes): the real
  // RunGlobalBundleAdjustment around the newest keyframe, one region size after the other on
  // the same map (each starts where the previous left it).
  if (regions.empty()) return;
  std::printf("\n## 2b. Regional global BA on the whole map (%zu keyframes; around its newest keyframe)\n\n",
              kfs.size());
  std::printf("| free keyframes (asked) | keyframes in the problem | points | wall [s] | CPU [s] | iterations | RMSE before -> after [px] |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  const auto map = std::const_pointer_cast<ServerMap>(biggest);  // the bench owns the back-end
  for (const int free : regions) {
    GlobalBaOptions o = options;
    o.linear_solver = solvers.front();
    o.max_free_keyframes = free;
    o.region_seeds = {kfs.back()->id()};
    const auto w0 = Clock::now();
    const double c0 = CpuSeconds();
    const GlobalBaReport r = RunGlobalBundleAdjustment(map, o, nullptr);
    std::printf("| %d (%d) | %d | %d | %.2f | %.2f | %d | %.3f -> %.3f |%s\n", r.free_keyframes, free, r.keyframes,
                r.points, std::chrono::duration<double>(Clock::now() - w0).count(), CpuSeconds() - c0, r.iterations,
                r.initial_rmse_px, r.final_rmse_px, r.outcome == GlobalBaReport::Outcome::kApplied ? "" : " not applied");
    std::fflush(stdout);
  }
}

void Throughput(const replay::Recording& rec, std::shared_ptr<const Vocabulary> vocab, const std::vector<int>& counts,
                double speed) {
  std::printf("\n## 3. Agents' streams at %.1fx their recorded rate, threaded back-end on this machine\n\n", speed);
  std::printf("| agents | keyframes/s offered | max backlog [batches] (~ [s] of data) | drain after last [s] | CPU load [cores] | keeps up |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const int n : counts) {
    const auto schedule = Schedule(rec, n);
    size_t kfs = 0;
    for (const auto& [t, b] : schedule) kfs += b.keyframes.size();
    const double span_s = schedule.back().first * 1e-9 / speed;
    ServerBackend backend(vocab, ServerOptions{});
    size_t max_backlog = 0;
    const double c0 = CpuSeconds();
    const auto start = Clock::now();
    {
      server::BackendRunner runner(&backend);
      for (const auto& [t, b] : schedule) {
        std::this_thread::sleep_until(start + std::chrono::nanoseconds(static_cast<int64_t>(t / speed)));
        backend.Submit(b);
        size_t backlog = 0;
        for (const auto& [a, q] : backend.Status().queues.agent_batches) backlog += q;
        max_backlog = std::max(max_backlog, backlog);
      }
      const auto last = Clock::now();
      backend.WaitUntilIdle();
      const double drain = std::chrono::duration<double>(Clock::now() - last).count();
      const double wall = std::chrono::duration<double>(Clock::now() - start).count();
      runner.Stop();
      const double load = (CpuSeconds() - c0) / wall;
      // Keeping up = the lag stays bounded: at most 10 s of data queued at any time (an
      // agent's B = 50 unacknowledged keyframes last ~15 s at hall3's rate) and everything
      // registered within 3 s of the last batch.
      const double lag_s = max_backlog / (schedule.size() / span_s);
      const bool ok = drain < 3.0 && lag_s < 10.0;
      std::printf("| %d | %.1f | %zu (%.1f) | %.1f | %.2f | %s |\n", n, kfs / span_s, max_backlog, lag_s, drain, load,
                  ok ? "yes" : "no");
      std::fflush(stdout);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string recording = CCM_TEST_RECORDING, vocab_path = CCM_SIM_VOCAB_FILE;
  std::vector<int> agents = {3, 6, 8, 10, 12};
  double speed = 1.0;
  bool skip_ba = false, skip_throughput = false, skip_registration = false;
  std::vector<size_t> ba_sizes = {100, 200, 400, 600, 800, 1000};
  GlobalBaOptions ba;
  ba.iterations = ServerOptions{}.optimization.global_ba_iterations;
  CLI::App app{"bench_server: server back-end timings on recorded agent streams"};
  app.add_option("--recording", recording, "ccm_replay --record file")->capture_default_str();
  app.add_option("--vocab", vocab_path, "vocabulary the recording was made with")->capture_default_str();
  app.add_option("--agents", agents, "agent counts for the throughput table")->delimiter(',');
  app.add_option("--speed", speed, "playback speed of the streams (1 = as recorded)")->capture_default_str();
  app.add_flag("--skip-ba", skip_ba, "skip the global BA table");
  app.add_flag("--skip-throughput", skip_throughput, "skip the throughput table");
  app.add_flag("--skip-registration", skip_registration, "skip the registration table");
  app.add_option("--ba-sizes", ba_sizes, "keyframe counts of the global BA table")->delimiter(',')->capture_default_str();
  app.add_option("--ba-iterations", ba.iterations, "iterations of each pass of the global BA")->capture_default_str();
  app.add_flag("--ba-inverse-depth", ba.low_parallax_inverse_depth,
               "points under --ba-min-parallax move as inverse depths from their first keyframe instead of being held");
  app.add_option("--ba-min-parallax", ba.min_parallax_deg, "points seen under less parallax [deg] are held fixed in the global BA (0: none)")->capture_default_str();
  app.add_option("--ba-threads", ba.threads, "Ceres threads of the global BA")->capture_default_str();
  std::vector<int> regions;
  size_t map_keyframes = 0;
  app.add_option("--map-keyframes", map_keyframes, "grow the map to at least this many keyframes (default: the largest --ba-sizes)");
  app.add_option("--ba-regions", regions, "free keyframes of regional global BAs on the whole map (e.g. 100,200,400)")
      ->delimiter(',');
  std::vector<std::string> solver_names = {"auto"};
  app.add_option("--ba-solver", solver_names, "linear solvers of the global BA (auto, sparse, iterative, dense; each size runs each)")
      ->delimiter(',')
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::vector<opt::BaLinearSolver> solvers;
  for (const std::string& name : solver_names) {
    if (!opt::ParseBaLinearSolver(name, &solvers.emplace_back())) {
      std::fprintf(stderr, "bench_server: unknown --ba-solver %s\n", name.c_str());
      return 2;
    }
  }
  std::string error;
  auto rec = replay::LoadRecording(recording, &error);
  if (!rec) {
    std::fprintf(stderr, "bench_server: %s\n  make one: ccm_replay --sim hall3 --record %s\n", error.c_str(),
                 recording.c_str());
    return 2;
  }
  auto loaded = LoadVocabularyFile(vocab_path, &error);
  if (!loaded) {
    std::fprintf(stderr, "bench_server: %s\n", error.c_str());
    return 2;
  }
  auto vocab = std::make_shared<const Vocabulary>(std::move(*loaded));
  std::printf("# bench_server: %s (%zu agents, %zu batches)\n", recording.c_str(), rec->agents.size(), rec->batches.size());
  if (!skip_registration) RegistrationTimes(*rec, vocab);
  if (!skip_ba) GlobalBaTimes(*rec, vocab, ba_sizes, ba, solvers, regions, map_keyframes);
  if (!skip_throughput) Throughput(*rec, vocab, agents, speed);
  return 0;
}
