// What ccm_server leaves in --out when it stops: every map, not only the largest. Two
// simulated agents in disjoint2's two rooms (100 m apart) with an empty vocabulary (no place
// recognition, so nothing can fuse) end in two maps; both must be written.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "server_runtime/server_outputs.h"
#include "slam_core/io/trajectory_io.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"
#include "tools/replay/replay_session.h"

namespace ccm::server {
namespace {

std::shared_ptr<const sim::Simulation> Disjoint2() {
  std::string error;
  const auto s = sim::LoadScenario("disjoint2", &error);
  return s ? std::shared_ptr<const sim::Simulation>(sim::Simulation::Create(*s, &error)) : nullptr;
}

TEST(ServerOutputs, EveryMapIsWrittenNotOnlyTheLargest) {
  const auto sim = Disjoint2();
  ASSERT_NE(sim, nullptr);
  replay::ReplayOptions o;
  o.final_global_ba = false;
  ServerBackend backend(std::make_shared<Vocabulary>(), o.BackendOptions());
  std::vector<replay::ReplayAgentInput> in;
  for (int a = 0; a < 2; ++a) {
    // The first 4 s of each flight at 10 Hz: both agents initialize and send keyframes.
    in.push_back({sim->agent_name(a), static_cast<AgentId>(a + 1), std::make_unique<sim::SimFrameSource>(sim, a, 0, 2, 40)});
  }
  const report::RunResult r = replay::RunReplay(std::move(in), o, &backend);
  ASSERT_EQ(r.error, "");
  const std::vector<MapSummary> maps = backend.Snapshot().Summaries();
  ASSERT_EQ(maps.size(), 2u) << "two rooms, no place recognition: two maps";

  const std::string dir = (std::filesystem::temp_directory_path() / ("ccm_server_outputs_" + std::to_string(::getpid()))).string();
  std::filesystem::remove_all(dir);
  std::string error;
  ASSERT_TRUE(WriteServerOutputs(dir, backend, ServerCommStats{}, {}, 1.0, &error)) << error;

  // Each map's file holds exactly its agent's keyframes there, at the back-end's poses.
  for (const MapSummary& m : maps) {
    ASSERT_EQ(m.agents.size(), 1u);
    const AgentId agent = *m.agents.begin();
    const std::string file = dir + "/map" + std::to_string(m.id.counter()) + "_agent" + std::to_string(agent) +
                             "_keyframes.tum";
    Trajectory written;
    ASSERT_TRUE(ReadTumTrajectory(file, &written).ok()) << file;
    std::vector<ServerKeyframePose> expected;
    for (const auto& p : backend.Snapshot().AgentTrajectory(agent)) {
      if (p.map == m.id) expected.push_back(p);
    }
    ASSERT_GE(expected.size(), 3u) << "agent " << agent << " sent keyframes";
    ASSERT_EQ(written.size(), expected.size()) << file;
    for (size_t i = 0; i < written.size(); ++i) {
      EXPECT_EQ(written[i].stamp_ns, expected[i].stamp_ns);
      EXPECT_LT((written[i].world_from_cam.translation() - expected[i].world_from_cam.translation()).norm(), 1e-6);
    }
  }
  std::ifstream f(dir + "/summary.json");
  const nlohmann::json summary = nlohmann::json::parse(f);
  ASSERT_EQ(summary["maps"].size(), 2u);
  std::set<int> agents_listed;
  int largest = 0;
  for (const auto& m : summary["maps"]) {
    ASSERT_EQ(m["agents"].size(), 1u);
    agents_listed.insert(m["agents"][0].get<int>());
    EXPECT_GT(m["keyframes"].get<int>(), 0);
    EXPECT_TRUE(m["accuracy"].is_null()) << "a live server has no ground truth";
    EXPECT_TRUE(std::filesystem::exists(dir + "/" + m["ply"].get<std::string>())) << m["ply"];
    EXPECT_TRUE(std::filesystem::exists(dir + "/" + m["parts"][0]["trajectory"].get<std::string>()));
    largest += m["largest"].get<bool>();
  }
  EXPECT_EQ(agents_listed, (std::set<int>{1, 2}));
  EXPECT_EQ(largest, 1);
  // The largest map's trajectories keep their old names (scripts read agent<id>_keyframes.tum).
  for (const char* name : {"agent1_keyframes.tum", "agent2_keyframes.tum", "server.json", "map.ply"}) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/" + name)) << name;
  }
  const cv::Mat top = cv::imread(dir + "/map_top.png");
  ASSERT_FALSE(top.empty());
  EXPECT_EQ(top.cols, 2 * top.rows) << "one panel per map, side by side";
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ccm::server
