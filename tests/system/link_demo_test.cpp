// System test of the protocol skeleton: one ccm_server and two ccm_agent processes, every
// process losing 20% of its incoming datagrams with 100 ms delay (wifi.xml). Each agent
// streams 40 full keyframes; the server must end with all 80 and both agents with every
// keyframe acknowledged (acks travel in BEST_EFFORT server messages; gaps are repaired by
// the agents' resend rule).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

nlohmann::json LastJsonLine(const std::string& output) {
  const auto start = output.rfind("\n{");
  return nlohmann::json::parse(output.substr(start == std::string::npos ? 0 : start + 1), nullptr, false);
}

TEST(LinkDemo, TwoAgentsOneServerUnderLossAllKeyframesAcked) {
  const std::string qos = std::string(CCM_QOS_DIR) + "/wifi.xml";
  const std::vector<std::string> faults = {"--qos", qos, "--domain", "181", "--drop", "0.2", "--delay-ms", "100",
                                           "--log-level", "warn"};
  std::vector<std::string> server = {CCM_SERVER, "--idle-exit", "8", "--duration", "120"};
  std::vector<std::string> agent1 = {CCM_AGENT, "--agent-id", "1", "--link-demo", "40", "--drain", "40"};
  std::vector<std::string> agent2 = {CCM_AGENT, "--agent-id", "2", "--link-demo", "40", "--drain", "40"};
  for (auto* cmd : {&server, &agent1, &agent2}) cmd->insert(cmd->end(), faults.begin(), faults.end());
  const auto results = testing::RunConcurrently({server, agent1, agent2}, ::testing::TempDir() + "/link_demo",
                                                std::chrono::seconds(150));
  for (const auto& r : results) EXPECT_EQ(r.exit_code, 0) << r.output;
  const auto srv = LastJsonLine(results[0].output);
  ASSERT_TRUE(srv.is_object()) << results[0].output;
  for (int i = 1; i <= 2; ++i) {
    const auto agent = LastJsonLine(results[i].output);
    ASSERT_TRUE(agent.is_object()) << results[i].output;
    EXPECT_EQ(agent["kfs_sent"], 40);
    EXPECT_EQ(agent["kfs_acked"], 40) << results[i].output;
    EXPECT_EQ(agent["kfs_unacked"], 0);
    EXPECT_EQ(agent["kfs_lost"], 0);
    EXPECT_EQ(srv["agents"][std::to_string(i)]["keyframes"], 40) << results[0].output;
  }
}

}  // namespace
}  // namespace ccm
