// ccm_server --ros2 live (issue 32, docs/ros2.md): a server and a simulated agent over DDS,
// and ccm_ros2_echo reading the rt/ topics with ROS 2's type names and QoS, as RViz2 would.
// The agent's path as received must match the simulator's ground truth (ccm_eval, Sim(3)).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include "tests/system/child_process.h"

namespace ccm {
namespace {

using testing::ChildProcess;

constexpr const char* kRos2Domain = "196";

// The agent flies to its end, the echo hears a round after its last keyframe, then the echo
// and the server stop; the echo's JSON line, or null after a failure (reported here).
nlohmann::json EchoAfterFlight(ChildProcess& server, ChildProcess& echo, ChildProcess& agent) {
  if (agent.Wait(std::chrono::seconds(300)) != 0) {
    ADD_FAILURE() << agent.Output() << "\n" << server.Output();
    return nullptr;
  }
  std::this_thread::sleep_for(std::chrono::seconds(3));
  echo.Signal(SIGTERM);
  const int echo_exit = echo.Wait(std::chrono::seconds(30));
  server.Signal(SIGTERM);
  const std::string out = echo.Output();
  const auto j = nlohmann::json::parse(out.substr(out.rfind("\n{") + 1), nullptr, false);
  if (echo_exit != 0 || !j.is_object()) {
    ADD_FAILURE() << "echo exit " << echo_exit << ": " << out << "\n" << server.Output();
    return nullptr;
  }
  return j;
}

TEST(Ros2, ALiveServersPathTfAndCloudReachARos2ReaderAndMatchTheGroundTruth) {
  const std::string dir = ::testing::TempDir() + "/ros2_live";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string qos = std::string(CCM_QOS_DIR) + "/wifi.xml";
  ChildProcess server({CCM_SERVER, "--qos", qos, "--domain", kRos2Domain, "--ros2", "--progress", "1000"},
                      dir + "/server.log");
  // The reader as a ROS 2 node is set up: Fast DDS' builtin transports (default.xml), not the
  // team's 1400 B Wi-Fi datagrams; the server's outputs use such a participant too.
  ChildProcess echo({CCM_ROS2_ECHO, "--qos", std::string(CCM_QOS_DIR) + "/default.xml", "--domain", kRos2Domain,
                     "--agent", "1", "--seconds", "600",
                     "--path-out", dir + "/path.tum"},
                    dir + "/echo.log");
  ChildProcess agent({CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0", "--max-frames", "500",
                      "--rate", "realtime", "--drain", "60", "--qos", qos, "--domain", kRos2Domain, "--ground-truth",
                      dir + "/gt.tum", "--log-level", "warn"},
                     dir + "/agent.log");
  ASSERT_TRUE(server.started() && echo.started() && agent.started());
  const nlohmann::json j = EchoAfterFlight(server, echo, agent);
  ASSERT_TRUE(j.is_object());
  EXPECT_GE(j["paths"].get<int>(), 10) << j.dump();  // one per second of flight
  EXPECT_EQ(j.value("frame_id", ""), "map") << j.dump();
  EXPECT_GE(j.value("poses", 0), 15) << j.dump();
  EXPECT_GE(j["tf"].get<int>(), 10);
  EXPECT_EQ(j["tf_frames"], nlohmann::json::array({"map>agent_1"})) << j.dump();
  ASSERT_TRUE(j.contains("cloud")) << j.dump();
  EXPECT_GE(j["cloud"]["width"].get<int>(), 500);
  EXPECT_EQ(j["cloud"]["frame_id"], "map");
  // The path as a ROS 2 tool got it, against the simulator's ground truth.
  const std::string json = dir + "/eval.json";
  const auto eval = testing::RunConcurrently(
      {{CCM_EVAL, "--gt", dir + "/gt.tum", "--est", dir + "/path.tum", "--json", json}}, dir + "/eval",
      std::chrono::seconds(60));
  ASSERT_EQ(eval[0].exit_code, 0) << eval[0].output;
  std::ifstream in(json);
  const auto e = nlohmann::json::parse(in, nullptr, false);
  ASSERT_TRUE(e.is_object()) << eval[0].output;
  const double ate = e["agents"][0]["ate_m"]["rmse"].get<double>();
  // hall3's agent 0 in a server map: 0.01-0.04 m in the collaboration tests; a wrong axis,
  // stamp or frame would be metres off.
  EXPECT_LT(ate, 0.1) << eval[0].output;
  std::printf("ros2 path: %d poses, ATE %.4f m against the ground truth\n", j["poses"].get<int>(), ate);
}

// A secure ground station (DDS-Security, docs/security.md) still shows its map to ROS 2 tools:
// the outputs come from a participant of their own on the open domain, while the team's
// participant admits only its PKI. The agent works as usual; a plain reader gets the path.
TEST(Ros2, ASecureServersOutputsReachAnOpenRos2Reader) {
  const std::string dir = ::testing::TempDir() + "/ros2_secure";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string pki = std::string(CCM_MAKE_PKI) + " " + dir + "/pki --agents 1 > " + dir + "/pki.log 2>&1";
  ASSERT_EQ(std::system(pki.c_str()), 0) << pki;
  const char* domain = "198";
  ChildProcess server({CCM_SERVER, "--qos", CCM_WIFI_SECURE_QOS, "--domain", domain, "--security-dir",
                       dir + "/pki/server", "--ros2", "--progress", "1000"},
                      dir + "/server.log");
  ChildProcess echo({CCM_ROS2_ECHO, "--qos", std::string(CCM_QOS_DIR) + "/default.xml", "--domain", domain, "--agent",
                     "1", "--seconds", "600"},
                    dir + "/echo.log");
  ChildProcess agent({CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0", "--max-frames", "300",
                      "--rate", "realtime", "--drain", "60", "--qos", CCM_WIFI_SECURE_QOS, "--domain", domain,
                      "--security-dir", dir + "/pki/agent_1", "--log-level", "warn"},
                     dir + "/agent.log");
  ASSERT_TRUE(server.started() && echo.started() && agent.started());
  const nlohmann::json j = EchoAfterFlight(server, echo, agent);
  ASSERT_TRUE(j.is_object());
  EXPECT_GE(j["paths"].get<int>(), 5) << j.dump() << "\n" << server.Output();
  EXPECT_EQ(j.value("frame_id", ""), "map") << j.dump();
  EXPECT_GE(j.value("poses", 0), 10) << j.dump();
  EXPECT_EQ(j["tf_frames"], nlohmann::json::array({"map>agent_1"})) << j.dump();
}

}  // namespace
}  // namespace ccm
