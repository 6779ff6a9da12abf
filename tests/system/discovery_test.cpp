// Discovery through a Fast DDS discovery server (issue 13): server, agent and ccm_ctl use the
// `ccm_participant_ds_client` profile of wifi.xml (CLIENT discovery, unicast only, no
// multicast anywhere), started by deploy/run-discovery-server.sh. Before the discovery
// server runs, ccm_ctl cannot find the running ccm_server (so discovery really goes through
// it); once it runs, the agent's keyframes reach the server and are acknowledged.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "tests/system/child_process.h"
#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

using testing::ChildProcess;

constexpr int kDiscoveryDomain = 189;
constexpr int kPort = 11947;  // not the default 11811: a real discovery server may run here

// wifi.xml with the client profile pointed at this test's discovery server port.
std::string WriteQos(const std::string& dir) {
  std::ifstream in(std::string(CCM_QOS_DIR) + "/wifi.xml");
  std::stringstream text;
  text << in.rdbuf();
  std::string xml = text.str();
  const std::string from = "<port>11811</port>", to = "<port>" + std::to_string(kPort) + "</port>";
  const auto at = xml.find(from);
  EXPECT_NE(at, std::string::npos) << "wifi.xml lost its discovery server locator";
  if (at != std::string::npos) xml.replace(at, from.size(), to);
  const std::string path = dir + "/wifi_ds.xml";
  std::ofstream(path) << xml;
  return path;
}

TEST(DiscoveryServer, ServerAndAgentMatchThroughTheDiscoveryServerOnly) {
  const std::string dir = ::testing::TempDir() + "/discovery";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string qos = WriteQos(dir);
  const std::vector<std::string> client = {"--qos", qos, "--domain", std::to_string(kDiscoveryDomain),
                                           "--participant-profile", "ccm_participant_ds_client"};
  auto with = [&](std::vector<std::string> cmd) {
    cmd.insert(cmd.end(), client.begin(), client.end());
    return cmd;
  };
  ChildProcess server(with({CCM_SERVER, "--progress", "1000", "--log-level", "info"}), dir + "/server.log");
  ASSERT_TRUE(server.started());

  // No discovery server yet: a client cannot find the running ccm_server.
  const auto lonely = testing::RunConcurrently({with({CCM_CTL, "status", "--timeout", "3"})}, dir + "/ctl0",
                                               std::chrono::seconds(20));
  EXPECT_EQ(lonely[0].exit_code, 1) << lonely[0].output;

  ChildProcess discovery({std::string(CCM_SOURCE_DIR) + "/deploy/run-discovery-server.sh", "--ip", "127.0.0.1",
                          "--port", std::to_string(kPort)},
                         dir + "/discovery.log");
  ASSERT_TRUE(discovery.started());
  const auto agent = testing::RunConcurrently(
      {with({CCM_AGENT, "--agent-id", "3", "--sim", "hall3", "--sim-agent", "0", "--max-frames", "240", "--rate",
             "realtime", "--drain", "30", "--log-level", "warn"})},
      dir + "/agent", std::chrono::seconds(90));
  ASSERT_EQ(agent[0].exit_code, 0) << agent[0].output << "\n" << server.Output() << "\n" << discovery.Output();
  const auto agent_json = nlohmann::json::parse(agent[0].output.substr(agent[0].output.rfind("\n{") + 1), nullptr, false);
  ASSERT_TRUE(agent_json.is_object()) << agent[0].output;
  EXPECT_GT(agent_json["link"]["kfs_acked"].get<int>(), 10) << agent[0].output;
  EXPECT_EQ(agent_json["link"]["kfs_unacked"].get<int>(), 0) << agent[0].output;

  const auto status = testing::RunConcurrently({with({CCM_CTL, "status", "--json", "--timeout", "5"})},
                                               dir + "/ctl1", std::chrono::seconds(20));
  ASSERT_EQ(status[0].exit_code, 0) << status[0].output;
  const auto s = nlohmann::json::parse(status[0].output.substr(status[0].output.find('{')), nullptr, false);
  ASSERT_TRUE(s.is_object()) << status[0].output;
  ASSERT_EQ(s["agents"].size(), 1u) << s.dump(1);
  EXPECT_EQ(s["agents"][0]["agent_id"], 3);
  EXPECT_GT(s["agents"][0]["keyframes_registered"].get<int>(), 10) << s.dump(1);

  ASSERT_TRUE(server.Signal(SIGTERM));
  EXPECT_EQ(server.Wait(std::chrono::seconds(60)), 0) << server.Output();
  ASSERT_TRUE(discovery.Signal(SIGTERM));
  EXPECT_NE(discovery.Wait(std::chrono::seconds(10)), -2) << "the discovery server ignored SIGTERM";
  std::cout << "through the discovery server: " << agent_json["link"]["kfs_acked"] << " keyframes acknowledged\n";
}

}  // namespace
}  // namespace ccm
