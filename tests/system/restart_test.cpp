// End-to-end restart (issue 11, loss and recovery): a server saves its map stack on exit; a
// new server process starts from it; the same agent id flies again (a restarted agent: new
// clock-derived ids, a fresh segment). The restarted server must accept the agent, keep the
// loaded keyframes, acknowledge every new keyframe and fuse the new segment into the loaded
// map (the agent flies the same stretch again, so place recognition must find it).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "tests/system/process_json.h"
#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

size_t KeyframesInMaps(const nlohmann::json& summary) {
  size_t n = 0;
  for (const auto& m : summary["maps"]) n += m["keyframes"].get<size_t>() + m["anchored_keyframes"].get<size_t>();
  return n;
}

struct Life {
  nlohmann::json server, agent, summary;
  std::string logs;
};

Life RunLife(const std::string& dir, const std::string& name, int domain, const std::vector<std::string>& map_args) {
  const std::vector<std::string> common = {"--qos", std::string(CCM_QOS_DIR) + "/wifi.xml", "--domain",
                                           std::to_string(domain), "--log-level", "warn"};
  std::vector<std::string> server = {CCM_SERVER, "--idle-exit", "4", "--duration", "180", "--out", dir + "/" + name};
  server.insert(server.end(), map_args.begin(), map_args.end());
  std::vector<std::string> agent = {CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0",
                                    "--max-frames", "300", "--rate", "realtime", "--drain", "60"};
  std::vector<std::vector<std::string>> cmds = {server, agent};
  for (auto& c : cmds) c.insert(c.end(), common.begin(), common.end());
  const auto results = testing::RunConcurrently(cmds, dir + "/" + name + "_run", std::chrono::seconds(200));
  Life life;
  for (size_t i = 0; i < results.size(); ++i) {
    life.logs += "---- " + name + " process " + std::to_string(i) + " (exit " + std::to_string(results[i].exit_code) +
                 ")\n" + results[i].output.substr(results[i].output.size() > 3000 ? results[i].output.size() - 3000 : 0);
    EXPECT_EQ(results[i].exit_code, 0) << name << " process " << i;
  }
  life.server = testing::LastJsonLine(results[0].output);
  life.agent = testing::LastJsonLine(results[1].output);
  life.summary = testing::ReadJsonFile(dir + "/" + name + "/summary.json");
  return life;
}

TEST(Restart, ServerReloadsItsSavedMapAndTheRestartedAgentFusesIntoIt) {
  const std::string dir = ::testing::TempDir() + "/restart";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string stack = dir + "/stack.ccmmap";
  const Life first = RunLife(dir, "first", 185, {"--save-map", stack});
  ASSERT_TRUE(first.agent.is_object() && first.summary.is_object()) << first.logs;
  ASSERT_TRUE(std::filesystem::exists(stack)) << first.logs;
  const size_t saved_kfs = KeyframesInMaps(first.summary);
  ASSERT_GT(saved_kfs, 20u) << first.logs;

  const Life second = RunLife(dir, "second", 186, {"--load-map", stack});
  ASSERT_TRUE(second.agent.is_object() && second.server.is_object() && second.summary.is_object()) << second.logs;
  // Every keyframe of the restarted agent reached the restarted server.
  EXPECT_EQ(second.agent["keyframes_lost"].get<int>(), 0);
  EXPECT_EQ(second.agent["link"]["kfs_unacked"].get<int>(), 0) << second.logs;
  EXPECT_GT(second.agent["link"]["kfs_acked"].get<int>(), 20);
  EXPECT_EQ(second.server["rejected"].get<int>(), 0);
  // The loaded keyframes are still there, the new ones came on top, and the new segment
  // (same place, new ids) was fused into the loaded map.
  EXPECT_GT(KeyframesInMaps(second.summary), saved_kfs + 20) << second.logs;
  EXPECT_GE(second.server["fusions"].get<int>(), 1) << "the new segment did not fuse into the loaded map\n"
                                                    << second.logs;
  std::cout << "saved " << saved_kfs << " keyframes; after the restart " << KeyframesInMaps(second.summary)
            << " in " << second.summary["maps"].size() << " map(s), fusions " << second.server["fusions"] << "\n";
}

}  // namespace
}  // namespace ccm
