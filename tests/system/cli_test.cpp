// The binaries' command lines: --help lists the options, bad configs fail clearly with a
// non-zero exit code.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "tests/server_runtime/daemon_config_template.h"
#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

testing::ProcessResult RunCli(std::vector<std::string> cmd) {
  return testing::RunConcurrently({cmd}, ::testing::TempDir() + "/cli", std::chrono::seconds(30))[0];
}

TEST(Cli, HelpListsOptions) {
  for (const char* binary : {CCM_AGENT, CCM_SERVER}) {
    const auto r = RunCli({binary, "--help"});
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("--config"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("--qos"), std::string::npos) << r.output;
  }
  EXPECT_NE(RunCli({CCM_AGENT, "--help"}).output.find("--agent-id"), std::string::npos);
}

TEST(Cli, BadConfigsFailWithClearErrors) {
  const std::string unknown = ::testing::TempDir() + "/agent_unknown.yaml";
  std::ofstream(unknown) << "agent_id: 2\nmax_keyframe: 10\n";
  auto r = RunCli({CCM_AGENT, "--config", unknown});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("max_keyframe"), std::string::npos) << r.output;

  const std::string wrong_type = ::testing::TempDir() + "/server_type.yaml";
  std::ofstream(wrong_type) << "publish_rate_hz: fast\n";
  r = RunCli({CCM_SERVER, "--config", wrong_type});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("publish_rate_hz"), std::string::npos) << r.output;

  r = RunCli({CCM_AGENT, "--config", "/nonexistent/agent.yaml"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("agent.yaml"), std::string::npos) << r.output;

  r = RunCli({CCM_AGENT, "--qos", "/nonexistent/qos.xml", "--sim", "hall3", "--max-frames", "1"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;

  r = RunCli({CCM_SERVER, "--duration", "1", "--drop", "1.5"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("drop probability"), std::string::npos) << r.output;
}

// Secure by default (issue 28): the packaged daemon config names a security directory; without
// its files the server does not start and says where they should be; --insecure is the
// explicit way out and warns.
TEST(Cli, PackagedServerConfigNeedsSecurityFilesOrAnExplicitInsecure) {
  const std::string dir = ::testing::TempDir() + "/cli_secure_default";
  const std::string yaml = testing::InstalledDaemonConfig(dir, dir);
  ASSERT_FALSE(yaml.empty());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(CCM_WIFI_SECURE_QOS, dir + "/wifi-secure.xml");
  std::ofstream(dir + "/server.yaml") << yaml;
  const std::vector<std::string> server = {CCM_SERVER, "--config", dir + "/server.yaml", "--domain", "189",
                                           "--duration", "1", "--no-final-ba"};
  auto r = RunCli(server);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(dir + "/security"), std::string::npos) << "the error names the directory:\n" << r.output;

  std::vector<std::string> insecure = server;
  insecure.push_back("--insecure");
  r = RunCli(insecure);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("DDS-Security is off"), std::string::npos) << r.output;
}

TEST(Cli, HonoursDefaultProfilesFileFromEnvironment) {
  // A QoS file given only through FASTRTPS_DEFAULT_PROFILES_FILE that does not exist must be
  // reported (proves the variable is read).
  setenv("FASTRTPS_DEFAULT_PROFILES_FILE", "/nonexistent/env_qos.xml", 1);
  const auto r = RunCli({CCM_SERVER, "--duration", "1"});
  unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("env_qos.xml"), std::string::npos) << r.output;
}

TEST(Cli, FleetRefusesBadInputClearly) {
  auto r = RunCli({CCM_FLEET, "--recording", "/nonexistent/a.ccmrec"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("a.ccmrec"), std::string::npos) << r.output;

  const std::string garbage = ::testing::TempDir() + "/garbage.ccmrec";
  std::ofstream(garbage) << "not a recording at all";
  r = RunCli({CCM_FLEET, "--recording", garbage, "--offline"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("garbage.ccmrec"), std::string::npos) << r.output;

  r = RunCli({CCM_FLEET, "--recording", garbage, "--speed", "0"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--speed"), std::string::npos) << r.output;

  r = RunCli({CCM_FLEET, "--recording", garbage, "--offline", "--score", garbage});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("exclude each other"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace ccm

namespace ccm {
namespace {

nlohmann::json AgentSummaryLine(const std::string& output) {
  const size_t at = output.rfind("\n{");
  return nlohmann::json::parse(at == std::string::npos ? output : output.substr(at + 1), nullptr, false);
}

// --skip-late-frames (the embedded profile): paced input acts as a camera that does not wait.
// At 20x hall3's rate a frame period is 2.5 ms, less than rendering one, so most frames are
// late: they are skipped and counted, and --max-frames still counts the frames read.
TEST(Cli, LateFramesAreSkippedAndCountedWhenAsked) {
  const std::vector<std::string> flight = {CCM_AGENT, "--standalone", "--sim", "hall3", "--max-frames", "60",
                                           "--rate", "20", "--log-level", "warn"};
  const auto paced = RunCli(flight);
  ASSERT_EQ(paced.exit_code, 0) << paced.output;
  const auto waited = AgentSummaryLine(paced.output);
  ASSERT_TRUE(waited.is_object()) << paced.output;
  EXPECT_EQ(waited["frames"].get<int>(), 60);
  EXPECT_EQ(waited["frames_skipped"].get<int>(), 0);
  std::vector<std::string> skipping = flight;
  skipping.push_back("--skip-late-frames");
  const auto late = RunCli(skipping);
  ASSERT_EQ(late.exit_code, 0) << late.output;
  const auto skipped = AgentSummaryLine(late.output);
  ASSERT_TRUE(skipped.is_object()) << late.output;
  EXPECT_EQ(skipped["frames"].get<int>() + skipped["frames_skipped"].get<int>(), 60) << skipped.dump();
  EXPECT_GE(skipped["frames_skipped"].get<int>(), 20) << skipped.dump();
  EXPECT_GE(skipped["frames"].get<int>(), 1);
  EXPECT_NE(late.output.find("frames skipped"), std::string::npos) << late.output;
}

}  // namespace
}  // namespace ccm
