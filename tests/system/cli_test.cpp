// The binaries' command lines: --help lists the options, bad configs fail clearly with a
// non-zero exit code.
#include <gtest/gtest.h>

#include <fstream>

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

TEST(Cli, HonoursDefaultProfilesFileFromEnvironment) {
  // A QoS file given only through FASTRTPS_DEFAULT_PROFILES_FILE that does not exist must be
  // reported (proves the variable is read).
  setenv("FASTRTPS_DEFAULT_PROFILES_FILE", "/nonexistent/env_qos.xml", 1);
  const auto r = RunCli({CCM_SERVER, "--duration", "1"});
  unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("env_qos.xml"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace ccm
