// The server as a daemon (issue 13): a ccm_server with --map-file is stopped with SIGTERM
// while an agent flies; it must finish its queued work, save the map stack and exit 0. A new
// server process on the same file reloads it, and the agent (never restarted) reconnects to
// it: its later keyframes reach the new server. `ccm_ctl status` (the ccm/server_status
// topic) is how the test watches both servers, so it is tested against a live server too.
// The first server runs with stdout "connected to journald" (JOURNAL_STREAM naming its log
// file), so its lines must carry sd-daemon priority prefixes.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include "tests/system/child_process.h"
#include "tests/system/ctl_status.h"
#include "tests/system/process_json.h"
#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

using testing::ChildProcess;

constexpr int kDomain = 187;

using testing::StatusAgent;
using testing::StatusMapKeyframes;
std::string Qos() { return testing::WifiQos(); }

std::vector<std::string> ServerCommand(const std::string& map_file, int domain = kDomain) {
  return {CCM_SERVER, "--qos", Qos(), "--domain", std::to_string(domain), "--map-file", map_file,
          "--autosave", "2", "--progress", "1000", "--log-level", "info"};
}

TEST(Daemon, SigtermSavesTheMapAndARestartedServerReloadsItAndTheAgentReconnects) {
  const std::string dir = ::testing::TempDir() + "/daemon";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string map_file = dir + "/state/stack.ccmmap";  // the daemon creates state/

  // "journald": the log file's device:inode in JOURNAL_STREAM, as systemd sets it.
  const std::string first_log = dir + "/server1.log";
  std::ofstream(first_log).put('\n');
  struct stat st {};
  ASSERT_EQ(stat(first_log.c_str(), &st), 0);
  const std::string journal = "JOURNAL_STREAM=" + std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);

  auto server = std::make_unique<ChildProcess>(ServerCommand(map_file), first_log, std::vector<std::string>{journal});
  ChildProcess agent({CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0", "--max-frames", "500",
                      "--rate", "realtime", "--drain", "30", "--qos", Qos(), "--domain", std::to_string(kDomain),
                      "--log-level", "warn"},
                     dir + "/agent.log");
  ASSERT_TRUE(server->started() && agent.started());

  // First life: the agent's keyframes arrive, the status shows them, an autosave happens.
  const nlohmann::json before = testing::WaitForCtlStatus(dir, std::chrono::seconds(40), [](const nlohmann::json& s) {
    const auto* a = StatusAgent(s, 1);
    return a != nullptr && (*a)["keyframes_registered"].get<int>() >= 15 && s["last_save_s"].get<double>() >= 0.0;
  }, kDomain);
  const auto* a1 = StatusAgent(before, 1);
  ASSERT_NE(a1, nullptr) << "no status with agent 1:\n" << before.dump(1) << "\n" << server->Output();
  EXPECT_TRUE((*a1)["alive"].get<bool>());
  EXPECT_GE((*a1)["keyframes_registered"].get<int>(), 15) << before.dump(1);
  EXPECT_GE(before["last_save_s"].get<double>(), 0.0) << "no autosave\n" << before.dump(1);
  EXPECT_EQ(before["map_file"], map_file);
  EXPECT_GE(before["maps"].size(), 1u);
  bool keyframe_traffic = false;
  for (const auto& t : before["traffic"]) {
    keyframe_traffic |= t["topic"] == "ccm/keyframes" && t["direction"] == "in" && t["bytes"].get<uint64_t>() > 0;
  }
  EXPECT_TRUE(keyframe_traffic) << before["traffic"].dump(1);

  // SIGTERM: clean exit, map saved.
  ASSERT_TRUE(server->Signal(SIGTERM));
  const int code = server->Wait(std::chrono::seconds(60));
  const std::string out1 = server->Output();
  ASSERT_EQ(code, 0) << out1;
  ASSERT_TRUE(std::filesystem::exists(map_file)) << out1;
  EXPECT_FALSE(std::filesystem::exists(map_file + ".tmp"));
  EXPECT_NE(out1.find("stopping on a signal"), std::string::npos) << out1;
  EXPECT_NE(out1.find("<6>exit: map stack saved to " + map_file), std::string::npos) << out1;
  EXPECT_NE(out1.find("<6>autosave: map stack saved"), std::string::npos) << out1;
  EXPECT_EQ(out1.find("[info]"), std::string::npos) << "journald lines must not carry time stamps:\n" << out1;
  server.reset();

  // Second life on the same file, the agent still flying.
  ChildProcess server2(ServerCommand(map_file), dir + "/server2.log");
  const nlohmann::json after = testing::WaitForCtlStatus(dir, std::chrono::seconds(40), [](const nlohmann::json& s) {
    const auto* a = StatusAgent(s, 1);
    return a != nullptr && (*a)["alive"].get<bool>() && (*a)["keyframes_registered"].get<int>() >= 3;
  }, kDomain);
  const std::string loaded_line = "loaded " + map_file;
  EXPECT_NE(server2.Output().find(loaded_line), std::string::npos) << server2.Output();
  const auto* a2 = StatusAgent(after, 1);
  ASSERT_NE(a2, nullptr) << "agent 1 did not reconnect:\n" << after.dump(1) << "\n" << server2.Output();
  EXPECT_GE((*a2)["keyframes_registered"].get<int>(), 3);
  // The reloaded keyframes are all there (plus the new ones).
  EXPECT_GE(StatusMapKeyframes(after), StatusMapKeyframes(before)) << before.dump(1) << after.dump(1);

  // The agent finishes its flight; the new server acknowledged everything it sent.
  EXPECT_EQ(agent.Wait(std::chrono::seconds(90)), 0) << agent.Output();
  const std::string agent_out = agent.Output();
  const auto agent_json = testing::LastJsonLine(agent_out);
  ASSERT_TRUE(agent_json.is_object()) << agent_out;
  EXPECT_EQ(agent_json["link"]["kfs_unacked"].get<int>(), 0) << agent_out;
  ASSERT_TRUE(server2.Signal(SIGINT));
  EXPECT_EQ(server2.Wait(std::chrono::seconds(60)), 0) << server2.Output();
  // Not a terminal, not the journal: plain time-stamped lines, no colour codes (Fast DDS'
  // own messages included: they go through the same logger).
  const std::string out2 = server2.Output();
  EXPECT_NE(out2.find("] [info] "), std::string::npos) << out2;
  EXPECT_EQ(out2.find('\x1b'), std::string::npos) << "colour codes in a log file:\n" << out2;
  EXPECT_EQ(out1.find('\x1b'), std::string::npos) << "colour codes in the journal:\n" << out1;
  std::cout << "first server: " << StatusMapKeyframes(before) << " KFs in status before SIGTERM; restarted server: "
            << StatusMapKeyframes(after) << " KFs once the agent was back; agent acked "
            << agent_json["link"]["kfs_acked"] << " KFs\n";
}

TEST(Daemon, SigkillMidFlightTheRestartLoadsTheLastAutosaveAndNoKeyframeIsLost) {
  // No clean stop: the process dies between autosaves (every 2 s). The map file on disk is
  // a complete generation (written, fsynced, renamed), the one before it is kept as .prev,
  // and a new server loads it; the agent, still flying, sees the new server's epoch, resends
  // what the killed server had acked but not saved, and ends with every keyframe
  // acknowledged, none lost.
  constexpr int kKillDomain = 186;
  const std::string dir = ::testing::TempDir() + "/daemon_kill";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string map_file = dir + "/stack.ccmmap";
  auto server = std::make_unique<ChildProcess>(ServerCommand(map_file, kKillDomain), dir + "/server1.log");
  ChildProcess agent({CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0", "--max-frames", "500",
                      "--rate", "realtime", "--drain", "30", "--qos", Qos(), "--domain", std::to_string(kKillDomain),
                      "--log-level", "warn"},
                     dir + "/agent.log");
  ASSERT_TRUE(server->started() && agent.started());
  const nlohmann::json before = testing::WaitForCtlStatus(
      dir, std::chrono::seconds(40),
      [](const nlohmann::json& s) {
        const auto* a = StatusAgent(s, 1);
        return a != nullptr && (*a)["keyframes_registered"].get<int>() >= 15 && s["last_save_s"].get<double>() >= 3.0;
      },
      kKillDomain);
  ASSERT_NE(StatusAgent(before, 1), nullptr) << before.dump(1) << "\n" << server->Output();
  ASSERT_TRUE(server->Signal(SIGKILL));
  server->Wait(std::chrono::seconds(10));
  const std::string out1 = server->Output();
  server.reset();
  ASSERT_TRUE(std::filesystem::exists(map_file)) << out1;
  EXPECT_TRUE(std::filesystem::exists(map_file + ".prev")) << "two autosaves keep a previous generation\n" << out1;

  ChildProcess server2(ServerCommand(map_file, kKillDomain), dir + "/server2.log");
  const nlohmann::json after = testing::WaitForCtlStatus(
      dir, std::chrono::seconds(40),
      [](const nlohmann::json& s) {
        const auto* a = StatusAgent(s, 1);
        return a != nullptr && (*a)["alive"].get<bool>() && (*a)["keyframes_registered"].get<int>() >= 3;
      },
      kKillDomain);
  EXPECT_NE(server2.Output().find("loaded " + map_file), std::string::npos) << server2.Output();
  EXPECT_EQ(server2.Output().find("previous generation"), std::string::npos) << "the newest file must load\n"
                                                                             << server2.Output();
  ASSERT_NE(StatusAgent(after, 1), nullptr) << after.dump(1) << "\n" << server2.Output();
  EXPECT_EQ(agent.Wait(std::chrono::seconds(90)), 0) << agent.Output();
  const std::string agent_out = agent.Output();
  const auto agent_json = testing::LastJsonLine(agent_out);
  ASSERT_TRUE(agent_json.is_object()) << agent_out;
  EXPECT_EQ(agent_json["link"]["kfs_unacked"].get<int>(), 0) << agent_out;
  EXPECT_EQ(agent_json["keyframes_lost"].get<int>(), 0) << agent_out;
  EXPECT_EQ(agent_json["link"]["server_restarts"].get<int>(), 1) << "the agent must see the new epoch\n" << agent_out;
  EXPECT_GT(agent_json["link"]["kfs_persisted"].get<int>(), 0) << agent_out;
  ASSERT_TRUE(server2.Signal(SIGTERM));
  EXPECT_EQ(server2.Wait(std::chrono::seconds(60)), 0) << server2.Output();
  std::cout << "killed with " << StatusMapKeyframes(before) << " KFs in status (last autosave at "
            << before["last_save_s"] << " s); the restarted server had " << StatusMapKeyframes(after)
            << " KFs once the agent was back; agent acked " << agent_json["link"]["kfs_acked"]
            << " KFs, resent " << agent_json["link"]["kfs_resent_after_restart"] << " after the restart\n";
}

TEST(Daemon, CtlReportsNoServerWithExitCode1) {
  const std::string dir = ::testing::TempDir() + "/daemon_ctl";
  std::filesystem::create_directories(dir);
  const auto r = testing::RunConcurrently(
      {{CCM_CTL, "status", "--domain", "188", "--qos", Qos(), "--timeout", "1"}}, dir + "/ctl", std::chrono::seconds(20));
  EXPECT_EQ(r[0].exit_code, 1) << r[0].output;
  EXPECT_NE(r[0].output.find("no server matched"), std::string::npos) << r[0].output;
}

}  // namespace
}  // namespace ccm
