// Heterogeneous cameras (CCM-SLAM's team mixes them): the same VO, unchanged, on the
// simulator's equidistant fisheye rendering of hall3 (752x480, f = 300 px, ~170 deg).
// Everything after feature extraction works on bearings through the camera model, so the
// fisheye must track as well as the pinhole camera.
#include <gtest/gtest.h>

#include "tests/sim/scenario.h"
#include "tests/slam_core/vo/vo_sim_run.h"

namespace ccm {
namespace {

TEST(VoFisheye, Hall3ExcerptTracksWithinHalfAPercentOfThePath) {
  std::string error;
  auto scenario = sim::LoadScenario("hall3", &error);
  ASSERT_TRUE(scenario) << error;
  scenario->camera = sim::FisheyeCamera();
  std::shared_ptr<const sim::Simulation> sim(sim::Simulation::Create(*scenario, &error));
  ASSERT_NE(sim, nullptr) << error;
  AckAll acks;
  const testing::VoSimRun run = testing::RunVoOnSim(sim, 0, 400, VoOptions{}, acks);
  ASSERT_GE(run.first_tracked_index, 0) << "never initialized";
  EXPECT_LT(run.first_tracked_index, 60) << "initialization took more than 3 s";
  const double tracked = static_cast<double>(run.tracked_after_init) / run.frames_after_init;
  EXPECT_GE(tracked, 0.95);
  EXPECT_EQ(run.segments, 1);
  ASSERT_GT(run.ate_rmse_m, 0.0) << run.error;
  EXPECT_LT(run.ate_rmse_m, 0.005 * run.path_length_m)
      << "ATE " << run.ate_rmse_m << " m over " << run.path_length_m << " m";
  std::printf("[fisheye] init at frame %lld, tracked %.3f, ATE %.4f m over %.1f m (%.3f %%), %lld keyframes\n",
              static_cast<long long>(run.first_tracked_index), tracked, run.ate_rmse_m, run.path_length_m,
              100.0 * run.ate_rmse_m / run.path_length_m, static_cast<long long>(run.stats.keyframes_created));
}

}  // namespace
}  // namespace ccm
