// ccm_replay's report on every map (server_runtime/run_report.h), on a made-up result whose
// truth is known: agents A and B share map 1, A at scale 0.5 and B at 0.55 of the ground
// truth (a fusion that got the scale 10 % wrong); agent C never fused and is alone in map 2.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slam_core/io/trajectory_io.h"
#include "tools/replay/dataset_spec.h"
#include "server_runtime/run_report.h"
#include "slam_core/server/server_backend.h"

namespace ccm {
namespace {

const MapId kMap1 = MapId::Make(0, 1), kMap2 = MapId::Make(0, 2);

// A curved flight of n poses (1 s apart) starting at x0, and its keyframes every 2nd frame
// in `map` under map_from_gt.
report::AgentRunResult Agent(const std::string& name, AgentId id, double x0, int n, MapId map,
                                const Sim3& map_from_gt) {
  report::AgentRunResult a;
  a.name = name;
  a.id = id;
  for (int i = 0; i < n; ++i) {
    const double t = 0.2 * i;
    const Eigen::Vector3d p(x0 + 3 * std::sin(t), 3 * (1 - std::cos(t)), 0.1 * i);
    const SE3 gt(Eigen::Quaterniond(Eigen::AngleAxisd(t, Eigen::Vector3d::UnitZ())), p);
    const int64_t stamp = (1000 + i) * 1000000000LL;
    a.ground_truth.push_back({stamp, gt});
    a.vo_keyframes.push_back({stamp, gt});
    if (i % 2 == 0) {
      a.server_keyframes.push_back({KeyframeId::Make(id, static_cast<uint64_t>(i + 1)), map, MapId::Make(id, 1), stamp,
                                    map_from_gt.TransformPose(gt), true});
    }
  }
  return a;
}

report::RunResult MadeUpResult() {
  const Sim3 to_map1(0.5, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())), {1, 2, 3});
  const Sim3 b_to_map1(0.55, to_map1.rotation(), to_map1.translation());
  report::RunResult r;
  r.agents.push_back(Agent("A", 1, 0.0, 30, kMap1, to_map1));
  r.agents.push_back(Agent("B", 2, 4.0, 30, kMap1, b_to_map1));
  r.agents.push_back(Agent("C", 3, 100.0, 20, kMap2, Sim3(2.0, Eigen::Quaterniond::Identity(), {0, 0, 0})));
  auto& c = r.agents.back().server_keyframes;  // every second one of C's keyframes anchored
  for (size_t k = 1; k < c.size(); k += 2) c[k].in_map = false;
  // Listed smaller map first: the report must still put the largest first.
  r.maps.push_back({kMap2, 10, 500, 0, {3}});
  r.maps.push_back({kMap1, 25, 900, 5, {1, 2}});
  return r;
}

TEST(ReplayReport, ScoresEveryMapWithItsAgentsAndScales) {
  const report::RunEvaluation ev = report::EvaluateRun(MadeUpResult());
  ASSERT_EQ(ev.map_scores.size(), 2u);
  EXPECT_EQ(ev.final_map, kMap1);
  const report::MapScore& m1 = ev.map_scores[0];
  const report::MapScore& m2 = ev.map_scores[1];
  EXPECT_EQ(m1.summary.id, kMap1);
  ASSERT_EQ(m1.agents.size(), 2u);
  ASSERT_TRUE(m1.scored && m2.scored);
  EXPECT_EQ(m1.agents[0].keyframes, 15u);
  // Each part's own alignment recovers its scale (gt metres per map unit).
  EXPECT_NEAR(m1.agents[0].scale_to_gt, 1 / 0.5, 1e-6);
  EXPECT_NEAR(m1.agents[1].scale_to_gt, 1 / 0.55, 1e-6);
  EXPECT_NEAR(m1.scale_ratio, 1.1, 1e-6);
  EXPECT_GT(m1.joint_ate_m.rmse, 0.05) << "the two parts disagree in scale: one alignment cannot fit both";
  // Each part alone is an exact similarity of its ground truth: perfect under its own
  // alignment, off under the joint one.
  for (const report::AgentInMap& part : m1.agents) {
    EXPECT_EQ(part.own_ate_m.count, 15u) << part.name;
    EXPECT_LT(part.own_ate_m.rmse, 1e-6) << part.name;
    EXPECT_GT(part.ate_m.rmse, 0.02) << part.name;
  }
  EXPECT_LT(ev.agents[0].part_ate_m.rmse, 1e-6);
  EXPECT_EQ(ev.agents[0].part_ate_m.count, 15u);
  EXPECT_GT(ev.agents[0].collaborative_ate_m.rmse, 0.02);
  ASSERT_EQ(m2.agents.size(), 1u);
  EXPECT_EQ(m2.agents[0].name, "C");
  EXPECT_NEAR(m2.agents[0].scale_to_gt, 0.5, 1e-6);
  EXPECT_LT(m2.joint_ate_m.rmse, 1e-6) << "an exact similarity of the ground truth";
  EXPECT_EQ(m2.scale_ratio, 0.0) << "one agent: no ratio";
  EXPECT_NEAR(m2.path_m, ev.agents[2].path_m * 18.0 / 19.0, 0.2) << "path between its first and last keyframe";
  // The headline numbers stay those of the largest map; C is not in it.
  EXPECT_DOUBLE_EQ(ev.collaborative_ate_m.rmse, m1.joint_ate_m.rmse);
  EXPECT_EQ(ev.agents[2].server_keyframes, 0u);
  EXPECT_EQ(ev.agents[2].collaborative_ate_m.count, 0u);
}

TEST(ReplayReport, WritesEveryMapsTrajectoriesSummaryAndPanels) {
  const report::RunResult r = MadeUpResult();
  const report::RunEvaluation ev = report::EvaluateRun(r);
  ServerBackend backend(std::make_shared<Vocabulary>(), ServerOptions{});
  const std::string dir = (std::filesystem::temp_directory_path() / ("ccm_replay_report_" + std::to_string(::getpid()))).string();
  std::filesystem::remove_all(dir);
  std::string error;
  ASSERT_TRUE(report::WriteRunOutputs(dir, r, ev, backend.Snapshot(), &error)) << error;
  const auto count = [&](const std::string& file) {
    Trajectory t;
    EXPECT_TRUE(ReadTumTrajectory(dir + "/" + file, &t).ok()) << file;
    return t.size();
  };
  EXPECT_EQ(count("map1_A_keyframes.tum"), 15u);
  EXPECT_EQ(count("map1_B_keyframes.tum"), 15u);
  EXPECT_EQ(count("map2_C_keyframes.tum"), 10u);
  EXPECT_EQ(count("A_keyframes.tum"), 15u) << "the largest map under the old name";
  EXPECT_FALSE(std::filesystem::exists(dir + "/map2_A_keyframes.tum"));
  EXPECT_EQ(count("C_vo_keyframes.tum"), 20u) << "the agent's own estimate, every keyframe it made";
  for (const char* f : {"map.ply", "map2.ply", "summary.json", "C_ground_truth.tum"}) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/" + f)) << f;
  }
  std::ifstream in(dir + "/summary.json");
  const nlohmann::json s = nlohmann::json::parse(in);
  ASSERT_EQ(s["maps"].size(), 2u);
  EXPECT_EQ(s["maps"][0]["id"], 1);
  EXPECT_TRUE(s["maps"][0]["largest"].get<bool>());
  EXPECT_EQ(s["maps"][0]["agents"], nlohmann::json::array({1, 2}));
  EXPECT_NEAR(s["maps"][0]["accuracy"]["scale_ratio"].get<double>(), 1.1, 1e-6);
  EXPECT_EQ(s["maps"][1]["agents"], nlohmann::json::array({3}));
  EXPECT_EQ(s["maps"][1]["parts"][0]["trajectory"], "map2_C_keyframes.tum");
  EXPECT_EQ(s["maps"][1]["parts"][0]["keyframes"], 10) << "anchored keyframes are part of the trajectory";
  EXPECT_EQ(s["maps"][1]["parts"][0]["full_keyframes"], 5);
  EXPECT_EQ(s["maps"][1]["parts"][0]["full_keyframe_s"], nlohmann::json::array({0.0, 4.0, 8.0, 12.0, 16.0}))
      << "the ones held in full, seconds after the agent's first keyframe in the map";
  EXPECT_EQ(s["maps"][0]["parts"][0]["full_keyframes"], 15);
  EXPECT_EQ(s["maps"][0]["parts"][0]["own_ate_m"]["count"], 15);
  EXPECT_LT(s["maps"][0]["parts"][0]["own_ate_m"]["rmse"].get<double>(), 1e-6);
  EXPECT_GT(s["maps"][0]["parts"][0]["ate_m"]["rmse"].get<double>(), 0.02);
  EXPECT_LT(s["agents"][0]["part_ate_m"]["rmse"].get<double>(), 1e-6);
  EXPECT_LT(s["maps"][1]["accuracy"]["joint_ate_m"]["rmse"].get<double>(), 1e-6);
  EXPECT_TRUE(s.contains("place_recognition"));
  const cv::Mat top = cv::imread(dir + "/map_top.png");
  EXPECT_EQ(top.cols, 1600);
  EXPECT_EQ(top.rows, 800);
  std::filesystem::remove_all(dir);
}

TEST(ReplayReport, DatasetSpecTakesAFrameRangeAfterTheLastAt) {
  std::string error;
  auto s = replay::ParseDatasetSpec("/data/kitti07/@60-159", &error);
  ASSERT_TRUE(s) << error;
  EXPECT_EQ(s->path, "/data/kitti07/");
  EXPECT_EQ(s->name, "kitti07_60-159");
  ASSERT_TRUE(s->range);
  EXPECT_EQ(s->range->first, 60);
  EXPECT_EQ(s->range->last, 159);
  s = replay::ParseDatasetSpec("/data/run@home", &error);
  ASSERT_TRUE(s) << "not a range: part of the path";
  EXPECT_EQ(s->path, "/data/run@home");
  EXPECT_FALSE(s->range);
  s = replay::ParseDatasetSpec("/data/ntsd@70-", &error);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->name, "ntsd_70-end");
  for (const char* bad : {"/data/x@60", "/data/x@9-3", "@1-2"}) {
    EXPECT_FALSE(replay::ParseDatasetSpec(bad, &error)) << bad;
    EXPECT_NE(error.find(bad), std::string::npos) << error;
  }
  std::vector<std::string> names = {"x", "y", "x", "x_2"};
  replay::MakeNamesUnique(&names);
  EXPECT_EQ(names, (std::vector<std::string>{"x", "y", "x_3", "x_2"}));
}

}  // namespace
}  // namespace ccm
