// Chaos with asserts (issue 28): the link cut for a whole minute in mid-flight, a disk that
// refuses the server's autosaves, and an agent SIGKILLed and restarted under its id. All run
// the real processes over wifi.xml; the server's SIGKILL restarts are Daemon.Sigkill* and
// tests/fault_harness/chaos_kill.sh, the flooding agent Flood.*, the grid of caps and longer
// cuts tests/fault_harness/link_chaos.sh.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "tests/system/child_process.h"
#include "tests/system/ctl_status.h"
#include "tests/system/process_json.h"
#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

using testing::ChildProcess;

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(Chaos, ALinkCutForAMinuteMidFlightLosesNoKeyframeAndTheAgentFliesOn) {
  // hall3's sim agent 0 flies its 80 s loop at real time; its participant is cut off from
  // 10 s to 70 s (nothing in or out). Its VO must not notice; ~3.5 keyframes/s wait
  // unacknowledged meanwhile, so B is sized for the minute (docs/protocol.md "N+B"). After
  // the cut DDS matches again (wifi.xml's 20 s lease ran out), the reliable writers and the
  // agent's resends bring every keyframe to the server.
  constexpr int kDomain = 189;
  const std::string dir = ::testing::TempDir() + "/chaos_cut";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/agent.yaml") << "buffer_keyframes: 250\n";
  const std::string domain = std::to_string(kDomain);
  ChildProcess server({CCM_SERVER, "--qos", testing::WifiQos(), "--domain", domain, "--out", dir + "/server",
                       "--progress", "1000", "--log-level", "info"},
                      dir + "/server.log");
  ChildProcess agent({CCM_AGENT, "-c", dir + "/agent.yaml", "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0",
                      "--max-frames", "1600", "--rate", "realtime", "--drain", "90", "--qos", testing::WifiQos(),
                      "--domain", domain, "--cut-at", "10", "--cut-s", "60", "--ground-truth", dir + "/gt.tum",
                      "--log-level", "info"},
                     dir + "/agent.log");
  ASSERT_TRUE(server.started() && agent.started());
  EXPECT_EQ(agent.Wait(std::chrono::seconds(240)), 0) << agent.Output();
  ASSERT_TRUE(server.Signal(SIGTERM));  // a clean stop: the final BA, then the outputs
  EXPECT_EQ(server.Wait(std::chrono::seconds(120)), 0) << server.Output();
  const std::string logs = "---- agent\n" + agent.Output() + "\n---- server\n" + server.Output();
  const auto a = testing::LastJsonLine(agent.Output());
  ASSERT_TRUE(a.is_object()) << logs;
  // The agent's autonomy: it tracked through the cut, in one segment.
  EXPECT_GE(a["tracked"].get<double>(), 0.95 * a["frames"].get<double>()) << logs;
  EXPECT_EQ(a["segments"].get<int>(), 1) << logs;
  // The cut took effect: keyframes waited for their ack through it.
  EXPECT_GE(a["link"]["ack_ms_max"].get<double>(), 40000.0) << logs;
  EXPECT_NE(server.Output().find("agent 1 left"), std::string::npos) << logs;
  EXPECT_NE(server.Output().find("agent 1 is back"), std::string::npos) << logs;
  // Nothing lost: every keyframe acknowledged, and every one the agent sent is in the map.
  EXPECT_EQ(a["keyframes_lost"].get<int>(), 0) << logs;
  EXPECT_EQ(a["keyframes_dropped_unpersisted"].get<int>(), 0) << logs;
  EXPECT_EQ(a["link"]["kfs_unacked"].get<int>(), 0) << logs;
  const auto summary = testing::ReadJsonFile(dir + "/server/summary.json");
  ASSERT_TRUE(summary.is_object()) << logs;
  EXPECT_EQ(summary["agents"][0]["keyframes_in_final_map"].get<int>(), a["link"]["kfs_sent"].get<int>()) << logs;
  // And the map is still right (one agent on hall3: 5-10 mm without a cut).
  const auto eval = testing::RunConcurrently({{CCM_EVAL, "--gt", dir + "/gt.tum", "--est",
                                               dir + "/server/agent1_keyframes.tum", "--json", dir + "/eval.json"}},
                                             dir + "/eval", std::chrono::seconds(60));
  const auto e = testing::ReadJsonFile(dir + "/eval.json");
  ASSERT_TRUE(eval[0].exit_code == 0 && e.is_object()) << eval[0].output;
  const double ate = e["agents"][0]["ate_m"]["rmse"].get<double>();
  EXPECT_LT(ate, 0.05) << logs;
  std::cout << "cut 60 s: " << a["link"]["kfs_sent"] << " KFs sent, " << a["link"]["kfs_acked"] << " acked, "
            << a["link"]["kfs_resent"] << " resent, longest wait for an ack " << a["link"]["ack_ms_max"]
            << " ms; server map ATE " << ate << " m\n";
}

TEST(Chaos, AutosavesThatFailForADiskLimitKeepTheLastGoodFileAndResumeAfterIt) {
  // A file-size limit on the running server (prlimit, as a full disk would) makes every
  // autosave fail half-written. The server must keep running, keep the last complete file,
  // not report those keyframes as persisted, and save again once the limit is lifted.
  if (std::system("prlimit --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "prlimit (util-linux) not found";
  constexpr int kDomain = 190;
  const std::string dir = ::testing::TempDir() + "/chaos_disk";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string map_file = dir + "/stack.ccmmap", domain = std::to_string(kDomain);
  ChildProcess server({CCM_SERVER, "--qos", testing::WifiQos(), "--domain", domain, "--map-file", map_file,
                       "--autosave", "2", "--progress", "1000", "--log-level", "info"},
                      dir + "/server.log");
  ChildProcess agent({CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0", "--max-frames", "700",
                      "--rate", "realtime", "--drain", "30", "--qos", testing::WifiQos(), "--domain", domain,
                      "--log-level", "warn"},
                     dir + "/agent.log");
  ASSERT_TRUE(server.started() && agent.started());
  const auto saved = testing::WaitForCtlStatus(
      dir, std::chrono::seconds(40),
      [](const nlohmann::json& s) {
        const auto* a = testing::StatusAgent(s, 1);
        return a != nullptr && (*a)["keyframes_registered"].get<int>() >= 15 && s["last_save_s"].get<double>() >= 3.0;
      },
      kDomain);
  ASSERT_NE(testing::StatusAgent(saved, 1), nullptr) << saved.dump(1) << server.Output();
  const std::string pid = std::to_string(server.pid());
  ASSERT_EQ(std::system(("prlimit --pid " + pid + " --fsize=4096:unlimited").c_str()), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // a save that was under way ends
  const auto good_size = std::filesystem::file_size(map_file);
  std::this_thread::sleep_for(std::chrono::seconds(8));
  const auto during = testing::CtlStatus(dir, kDomain);
  const std::string failing_log = server.Output();
  ASSERT_TRUE(during.is_object()) << failing_log;
  EXPECT_TRUE(server.running()) << failing_log;
  EXPECT_GE(Count(failing_log, "saving the map stack failed"), 2u) << failing_log;
  EXPECT_EQ(std::filesystem::file_size(map_file), good_size) << "a failed save touched the last good file";
  EXPECT_FALSE(std::filesystem::exists(map_file + ".tmp")) << "a failed save left its temp file";
  ASSERT_EQ(std::system(("prlimit --pid " + pid + " --fsize=unlimited").c_str()), 0);
  EXPECT_EQ(agent.Wait(std::chrono::seconds(90)), 0) << agent.Output();
  const auto a = testing::LastJsonLine(agent.Output());
  ASSERT_TRUE(a.is_object()) << agent.Output();
  EXPECT_EQ(a["keyframes_lost"].get<int>(), 0) << agent.Output();
  EXPECT_EQ(a["keyframes_dropped_unpersisted"].get<int>(), 0) << agent.Output();
  EXPECT_EQ(a["link"]["kfs_unacked"].get<int>(), 0) << agent.Output();
  EXPECT_GT(a["link"]["kfs_persisted"].get<int>(), 0) << agent.Output();
  // Saves resumed: the status' last save is newer than any the failing period could make.
  const auto after = testing::WaitForCtlStatus(
      dir, std::chrono::seconds(20),
      [&](const nlohmann::json& s) { return s["last_save_s"].get<double>() > during["last_save_s"].get<double>(); },
      kDomain);
  EXPECT_GT(after["last_save_s"].get<double>(), during["last_save_s"].get<double>()) << server.Output();
  EXPECT_GT(std::filesystem::file_size(map_file), good_size);
  ASSERT_TRUE(server.Signal(SIGTERM));
  EXPECT_EQ(server.Wait(std::chrono::seconds(60)), 0) << server.Output();
  // The file the server left loads.
  ChildProcess reload({CCM_SERVER, "--qos", testing::WifiQos(), "--domain", domain, "--map-file", map_file,
                       "--autosave", "0", "--duration", "1", "--log-level", "info"},
                      dir + "/reload.log");
  EXPECT_EQ(reload.Wait(std::chrono::seconds(60)), 0) << reload.Output();
  EXPECT_NE(reload.Output().find("loaded " + map_file), std::string::npos) << reload.Output();
  std::cout << "saves failed " << Count(failing_log, "saving the map stack failed") << " times; agent acked "
            << a["link"]["kfs_acked"] << ", persisted " << a["link"]["kfs_persisted"] << ", lost "
            << a["keyframes_lost"] << "\n";
}

TEST(Chaos, AnAgentSigkilledMidFlightRestartsUnderItsIdAndTheServerKeepsBothLives) {
  // An onboard computer that crashes and reboots: agent 1 is SIGKILLed mid-flight (no drain,
  // its DDS participant gone without a goodbye) and started again with the same id, flying
  // the same stretch. The server must keep what the first life registered, take the second
  // life as a new segment of the same agent, acknowledge all of it and fuse the two.
  constexpr int kDomain = 191;
  const std::string dir = ::testing::TempDir() + "/chaos_agent_kill";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string domain = std::to_string(kDomain);
  const std::vector<std::string> agent_args = {CCM_AGENT, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0",
                                               "--rate", "realtime", "--drain", "60", "--qos", testing::WifiQos(),
                                               "--domain", domain, "--log-level", "info", "--max-frames"};
  ChildProcess server({CCM_SERVER, "--qos", testing::WifiQos(), "--domain", domain, "--out", dir + "/server",
                       "--progress", "1000", "--log-level", "info"},
                      dir + "/server.log");
  auto first_args = agent_args;
  first_args.push_back("1200");
  ChildProcess first(first_args, dir + "/first.log");
  ASSERT_TRUE(server.started() && first.started());
  const auto before = testing::WaitForCtlStatus(
      dir, std::chrono::seconds(60),
      [](const nlohmann::json& s) {
        const auto* a = testing::StatusAgent(s, 1);
        return a != nullptr && (*a)["keyframes_registered"].get<int>() >= 30;
      },
      kDomain);
  const auto* before_agent = testing::StatusAgent(before, 1);
  ASSERT_NE(before_agent, nullptr) << before.dump(1) << server.Output() << first.Output();
  const int registered_first = (*before_agent)["keyframes_registered"].get<int>();
  ASSERT_TRUE(first.Signal(SIGKILL));
  first.Wait(std::chrono::seconds(10));
  auto second_args = agent_args;
  second_args.push_back("500");
  ChildProcess second(second_args, dir + "/second.log");
  ASSERT_TRUE(second.started());
  EXPECT_EQ(second.Wait(std::chrono::seconds(150)), 0) << second.Output();
  EXPECT_TRUE(server.running()) << server.Output();
  ASSERT_TRUE(server.Signal(SIGTERM));
  EXPECT_EQ(server.Wait(std::chrono::seconds(120)), 0) << server.Output();
  const std::string logs = "---- second life\n" + second.Output() + "\n---- server\n" + server.Output();
  const auto a = testing::LastJsonLine(second.Output());
  ASSERT_TRUE(a.is_object()) << logs;
  // The second life: every keyframe acknowledged, none lost.
  EXPECT_EQ(a["keyframes_lost"].get<int>(), 0) << logs;
  EXPECT_EQ(a["link"]["kfs_unacked"].get<int>(), 0) << logs;
  EXPECT_GT(a["link"]["kfs_acked"].get<int>(), 20) << logs;
  const auto summary = testing::ReadJsonFile(dir + "/server/summary.json");
  ASSERT_TRUE(summary.is_object() && summary["agents"].size() == 1u) << logs;
  const auto& agent = summary["agents"][0];
  // One agent with both lives' keyframes: what the first registered before the kill stays
  // (registered counts full keyframes only; the final map also holds the anchors).
  EXPECT_GE(agent["segments"].get<int>(), 2) << logs;
  EXPECT_GE(agent["keyframes_in_final_map"].get<int>(), registered_first + a["link"]["kfs_sent"].get<int>()) << logs;
  // The same stretch flown twice: the second life's segment fused into the first's map.
  EXPECT_GE(summary["fusions"].get<int>(), 1) << logs;
  EXPECT_EQ(summary["maps"].size(), 1u) << logs;
  std::cout << "first life: " << registered_first << " keyframes registered before the SIGKILL; second life: "
            << a["link"]["kfs_acked"] << " acked, " << a["keyframes_lost"] << " lost; server: "
            << agent["keyframes_registered"] << " registered, " << agent["keyframes_in_final_map"]
            << " in the final map, " << summary["maps"].size() << " map(s), " << summary["fusions"] << " fusion(s)\n";
}

}  // namespace
}  // namespace ccm
