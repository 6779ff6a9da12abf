// Benchmark of the agent VO on the simulator: tracking ms/frame (median, p95) and local
// mapping ms/keyframe for several local-map sizes N (CCM-SLAM Table: tracking 23-28 ms,
// mapping 82-330 ms), plus tracked fraction and ATE. Not a test: prints a table.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>

#include "tests/slam_core/vo/vo_sim_run.h"

int main(int argc, char** argv) {
  CLI::App app{"bench_vo: agent VO timings and accuracy on a simulated agent"};
  std::string scenario = "hall3";
  int agent = 0;
  int64_t frames = 600;
  std::vector<int> sizes = {10, 20, 50, 100};
  app.add_option("--scenario", scenario, "built-in scenario or YAML file")->capture_default_str();
  app.add_option("--agent", agent, "agent index")->capture_default_str();
  app.add_option("--frames", frames, "frames to run (-1: whole flight)")->capture_default_str();
  app.add_option("--sizes", sizes, "local map sizes N to test")->capture_default_str();
  double fast_adapt = -1.0;
  app.add_option("--fast-adapt", fast_adapt,
                 "ORB: adaptive FAST threshold band [H/2, H] x target corners per level; 0 = fixed threshold "
                 "(default: the extractor's)");
  CLI11_PARSE(app, argc, argv);

  std::string error;
  const auto sim = ccm::testing::LoadSimulation(scenario, &error);
  if (!sim) {
    std::fprintf(stderr, "bench_vo: %s\n", error.c_str());
    return 1;
  }
  std::printf("scenario %s agent %d, %lld frames, 752x480, 1000 features, one thread (synchronous mapping)\n",
              scenario.c_str(), agent, static_cast<long long>(frames));
  std::printf("%5s %10s %10s %10s %10s %8s %6s %9s %9s %8s\n", "N", "track_med", "track_p95", "map_med",
              "map_p95", "tracked", "KFs", "ATE_m", "path_m", "ATE_%");
  for (const int n : sizes) {
    ccm::VoOptions o;
    o.bound.max_keyframes = n;
    if (fast_adapt >= 0.0) {
      o.orb.adapt_high_ratio = fast_adapt;
      o.orb.adapt_low_ratio = fast_adapt / 2;
    }
    o.bound.max_unacked_buffer = n;
    ccm::AckAll acks;
    const auto run = ccm::testing::RunVoOnSim(sim, agent, frames, o, acks);
    const double tracked = run.frames_after_init ? static_cast<double>(run.tracked_after_init) / run.frames_after_init : 0;
    std::printf("%5d %10.2f %10.2f %10.2f %10.2f %7.1f%% %6lld %9.4f %9.2f %7.2f%%\n", n,
                ccm::Percentile(run.stats.tracking_ms, 0.5), ccm::Percentile(run.stats.tracking_ms, 0.95),
                ccm::Percentile(run.stats.mapping_ms, 0.5), ccm::Percentile(run.stats.mapping_ms, 0.95), 100 * tracked,
                static_cast<long long>(run.stats.keyframes_created), run.ate_rmse_m, run.path_length_m,
                run.path_length_m > 0 ? 100 * run.ate_rmse_m / run.path_length_m : 0.0);
    std::fflush(stdout);
  }
  return 0;
}
