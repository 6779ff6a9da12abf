// An agent flying through a map the server shared with it must keep making keyframes of its
// own: the points it tracks there are mostly the other agent's, so a keyframe rule that
// counts only its last keyframe's points never sees the view moving on (issue 27, fresh
// seed 2112: no keyframe for 123 frames, then lost, a second segment, VO 0.67 m off).
#include <gtest/gtest.h>

#include <cstdio>

#include "server_runtime/run_report.h"
#include "tests/sim/scenario.h"
#include "tests/sim/scene_generator.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/slam_core/server/server_test_util.h"
#include "tools/replay/replay_session.h"

namespace ccm {
namespace {

TEST(ServerScenario, SharedMapKeepsTheAgentsOwnKeyframesComing) {
  // A room, 2 agents (VGA, 15 Hz, motion blur) that overlap early; bench_fusion's scene of
  // seed 2112 with --max-agents 4. The first 22 s of each flight: agent 2 got lost at 17.6 s.
  sim::SceneGeneratorOptions gen;
  gen.max_agents = 4;
  const sim::GeneratedScene scene = sim::GenerateScene(2112, gen);
  std::string error;
  const auto scenario = sim::ParseScenarioYaml(scene.yaml, "gen:2112", &error);
  ASSERT_TRUE(scenario) << error;
  std::shared_ptr<const sim::Simulation> sim(sim::Simulation::Create(*scenario, &error).release());
  ASSERT_NE(sim, nullptr) << error;
  ASSERT_EQ(sim->num_agents(), 2);
  constexpr int64_t kFrames = 330;
  std::vector<replay::ReplayAgentInput> in;
  for (int a = 0; a < 2; ++a) {
    in.push_back({sim->agent_name(a), static_cast<AgentId>(a + 1),
                  std::make_unique<sim::SimFrameSource>(sim, a, 0, 1, kFrames)});
  }
  replay::ReplayOptions o;
  ASSERT_TRUE(o.map_sharing);
  ServerBackend backend(testing::SimVocabulary(), o.BackendOptions());
  const report::RunResult r = replay::RunReplay(std::move(in), o, &backend);
  ASSERT_EQ(r.error, "");
  ASSERT_GE(r.stats.fusions, 1) << "the two agents' maps must fuse for anything to be shared";
  const report::RunEvaluation ev = report::EvaluateRun(r);
  for (size_t i = 0; i < r.agents.size(); ++i) {
    const report::AgentRunResult& a = r.agents[i];
    std::printf("  %s: %lld/%lld frames tracked, %d segment(s), %lld keyframes, VO ATE %.4f m\n", a.name.c_str(),
                static_cast<long long>(a.frames_tracked), static_cast<long long>(a.frames), a.segments,
                static_cast<long long>(a.keyframes_created), ev.agents[i].standalone_ate_m.rmse);
    EXPECT_EQ(a.segments, 1) << a.name << " lost track";
    EXPECT_GE(a.frames_tracked, a.frames * 95 / 100) << a.name;
    // Without the agent's own keyframes: 0.67 m over the full flight, lost at frame 264.
    EXPECT_LT(ev.agents[i].standalone_ate_m.rmse, 0.1) << a.name;
  }
}

}  // namespace
}  // namespace ccm
