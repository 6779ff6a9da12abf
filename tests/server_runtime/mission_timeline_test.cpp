// MissionTimeline: each row's window figures count only what is new since the previous row
// (keyframes of every agent, global BAs), the totals are the back-end's, and the file gets
// one JSON object per line.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "server_runtime/mission_timeline.h"

namespace ccm::server {
namespace {

MapSummary Map(size_t keyframes, size_t anchored, size_t points) {
  MapSummary m;
  m.keyframes = keyframes;
  m.anchored = anchored;
  m.map_points = points;
  return m;
}

TEST(MissionTimeline, AWindowCountsOnlyWhatIsNewSinceThePreviousRow) {
  MissionTimeline timeline;
  BackendStatus status;
  status.stats.agents[1].keyframe_ms = {10, 20, 30};
  status.stats.agents[2].keyframe_ms = {40};
  status.stats.global_ba_seconds = {{50, 0.4}};
  status.stats.global_ba_applied = 1;
  status.queues.agent_batches = {{1, 2}, {2, 7}};
  const nlohmann::json first = timeline.Row(10.0, 123.4, status, {Map(40, 5, 900), Map(12, 0, 300)});
  EXPECT_EQ(first["keyframes"], 52);
  EXPECT_EQ(first["anchored"], 5);
  EXPECT_EQ(first["map_points"], 1200);
  EXPECT_EQ(first["maps"], 2);
  EXPECT_EQ(first["keyframes_in_window"], 4);
  EXPECT_DOUBLE_EQ(first["keyframe_ms_median"].get<double>(), 30.0);  // of 10 20 30 40
  EXPECT_DOUBLE_EQ(first["keyframe_ms_p95"].get<double>(), 40.0);
  EXPECT_EQ(first["global_bas_in_window"], 1);
  EXPECT_DOUBLE_EQ(first["global_ba_s_max"].get<double>(), 0.4);
  EXPECT_EQ(first["global_ba_keyframes"], 50);
  EXPECT_EQ(first["deepest_queue"], 7);
  EXPECT_DOUBLE_EQ(first["rss_mb"].get<double>(), 123.4);

  // Later: agent 1 processed two more keyframes, agent 3 joined, two more global BAs.
  status.stats.agents[1].keyframe_ms = {10, 20, 30, 100, 200};
  status.stats.agents[3].keyframe_ms = {300};
  status.stats.global_ba_seconds = {{50, 0.4}, {90, 2.5}, {95, 1.0}};
  status.stats.global_ba_applied = 3;
  status.queues.agent_batches.clear();
  const nlohmann::json second = timeline.Row(20.0, 130.0, status, {Map(60, 9, 1500)});
  EXPECT_EQ(second["keyframes_in_window"], 3);
  EXPECT_DOUBLE_EQ(second["keyframe_ms_median"].get<double>(), 200.0);
  EXPECT_EQ(second["global_bas_in_window"], 2);
  EXPECT_DOUBLE_EQ(second["global_ba_s_max"].get<double>(), 2.5);
  EXPECT_EQ(second["global_ba_keyframes"], 90);
  EXPECT_EQ(second["global_bas"], 3);
  EXPECT_EQ(second["deepest_queue"], 0);

  // Nothing new: an empty window, not the previous one again.
  const nlohmann::json third = timeline.Row(30.0, 130.0, status, {Map(60, 9, 1500)});
  EXPECT_EQ(third["keyframes_in_window"], 0);
  EXPECT_EQ(third["global_bas_in_window"], 0);
  EXPECT_DOUBLE_EQ(third["global_ba_s_max"].get<double>(), 0.0);
}

TEST(MissionTimeline, TheFileHasOneJsonObjectPerRowAndAnUnwritablePathIsAClearError) {
  const std::string dir = ::testing::TempDir() + "/mission_timeline";
  std::filesystem::create_directories(dir);
  MissionTimelineFile file;
  std::string error;
  ASSERT_TRUE(file.Open(dir + "/timeline.jsonl", &error)) << error;
  file.Append({{"t_s", 1.0}});
  file.Append({{"t_s", 2.0}});
  std::ifstream in(dir + "/timeline.jsonl");
  std::string line;
  std::vector<double> t;
  while (std::getline(in, line)) t.push_back(nlohmann::json::parse(line)["t_s"].get<double>());
  EXPECT_EQ(t, (std::vector<double>{1.0, 2.0}));

  MissionTimelineFile bad;
  EXPECT_FALSE(bad.Open(dir + "/no/such/dir/timeline.jsonl", &error));
  EXPECT_NE(error.find("timeline"), std::string::npos) << error;
  bad.Append({{"t_s", 1.0}});  // a closed file ignores rows
}

}  // namespace
}  // namespace ccm::server
