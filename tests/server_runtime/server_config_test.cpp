#include "server_runtime/server_config.h"
#include "runtime_common/runtime_cli.h"
#include "tests/server_runtime/daemon_config_template.h"

#include <gtest/gtest.h>

#include <fstream>

namespace ccm::server {
namespace {

TEST(ServerConfig, LoadsAndValidates) {
  const std::string path = ::testing::TempDir() + "/server.yaml";
  std::ofstream(path) << "publish_rate_hz: 0.5\nack_repeats: 4\nack_points: true\n";
  ServerConfig c;
  std::string error;
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_DOUBLE_EQ(c.publish_rate_hz, 0.5);
  EXPECT_EQ(c.ack_repeats, 4);
  EXPECT_TRUE(c.ack_points);

  const std::string bad = ::testing::TempDir() + "/server_bad.yaml";
  std::ofstream(bad) << "ack_repeats: 0\n";
  EXPECT_FALSE(LoadServerConfig(bad, &c, &error));
  EXPECT_NE(error.find("ack_repeats"), std::string::npos) << error;
}

TEST(ServerConfig, DaemonKeysLoadAndAreChecked) {
  const std::string path = ::testing::TempDir() + "/server_daemon.yaml";
  std::ofstream(path) << "map_file: /var/lib/x/stack.ccmmap\nautosave_s: 30\nstatus_period_s: 0.5\n"
                         "participant_profile: ccm_participant_ds_client\n";
  ServerConfig c;
  std::string error;
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_EQ(c.map_file, "/var/lib/x/stack.ccmmap");
  EXPECT_DOUBLE_EQ(c.autosave_s, 30.0);
  EXPECT_DOUBLE_EQ(c.status_period_s, 0.5);
  EXPECT_EQ(c.participant_profile, "ccm_participant_ds_client");
  // A sub-second autosave would save continuously; 0 switches it off.
  std::ofstream(path) << "autosave_s: 0.2\n";
  EXPECT_FALSE(LoadServerConfig(path, &c, &error));
  EXPECT_NE(error.find("autosave_s"), std::string::npos) << error;
  std::ofstream(path) << "autosave_s: 0\n";
  EXPECT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  // A slot is released only after the agent was declared gone; 0 never releases one.
  std::ofstream(path) << "agent_slot_release_s: 120\n";
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_DOUBLE_EQ(c.agent_slot_release_s, 120.0);
  std::ofstream(path) << "agent_slot_release_s: 1\nliveliness_timeout_s: 3\n";
  EXPECT_FALSE(LoadServerConfig(path, &c, &error));
  EXPECT_NE(error.find("agent_slot_release_s"), std::string::npos) << error;
  std::ofstream(path) << "agent_slot_release_s: 0\n";
  EXPECT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  // The region of a big map's global BA: a count, 0 for the whole map.
  std::ofstream(path) << "global_ba_max_free_keyframes: 250\n";
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_EQ(c.global_ba_max_free_keyframes, 250);
  std::ofstream(path) << "global_ba_min_parallax_deg: 1.5\nglobal_ba_low_parallax_inverse_depth: true\n";
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_DOUBLE_EQ(c.global_ba_min_parallax_deg, 1.5);
  EXPECT_TRUE(c.global_ba_low_parallax_inverse_depth);
  EXPECT_FALSE(ServerConfig{}.global_ba_low_parallax_inverse_depth) << "off by default";
  std::ofstream(path) << "global_ba_low_parallax_inverse_depth: perhaps\n";
  EXPECT_FALSE(LoadServerConfig(path, &c, &error));
  EXPECT_NE(error.find("global_ba_low_parallax_inverse_depth"), std::string::npos) << error;
  std::ofstream(path) << "global_ba_min_parallax_deg: 90\n";
  EXPECT_FALSE(LoadServerConfig(path, &c, &error));
  EXPECT_NE(error.find("global_ba_min_parallax_deg"), std::string::npos) << error;
  std::ofstream(path) << "global_ba_max_free_keyframes: -1\n";
  EXPECT_FALSE(LoadServerConfig(path, &c, &error));
  EXPECT_NE(error.find("global_ba_max_free_keyframes"), std::string::npos) << error;
  // Repeated passes: on by default, 0 turns it off, a ratio of 1 or more is refused.
  EXPECT_GT(ServerConfig{}.revisit_distance_ratio, 0.0);
  ServerConfig r;
  std::ofstream(path) << "revisit_distance_ratio: 0\n";
  ASSERT_TRUE(LoadServerConfig(path, &r, &error)) << error;
  EXPECT_EQ(r.revisit_distance_ratio, 0.0);
  std::ofstream(path) << "revisit_distance_ratio: 1.5\n";
  EXPECT_FALSE(LoadServerConfig(path, &r, &error));
  EXPECT_NE(error.find("revisit_distance_ratio"), std::string::npos) << error;
}

// The config the ccm-server package installs (its @CCM_CONFDIR@ filled in as at install time).
TEST(ServerConfig, InstalledDaemonConfigLoads) {
  const std::string yaml = testing::InstalledDaemonConfig("/etc/ccm-slam-dds");
  ASSERT_FALSE(yaml.empty());
  const std::string path = ::testing::TempDir() + "/server_installed.yaml";
  std::ofstream(path) << yaml;
  ServerConfig c;
  std::string error;
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_EQ(c.qos_file, "/etc/ccm-slam-dds/wifi-secure.xml");
  EXPECT_EQ(c.security_dir, "/etc/ccm-slam-dds/security") << "the packaged daemon is secure by default";
  EXPECT_FALSE(c.insecure);
  EXPECT_EQ(c.map_file, "/var/lib/ccm-slam-dds/map_stack.ccmmap");
  EXPECT_GT(c.autosave_s, 0.0);
}

// The explicit way out of the secure default: the participant starts without security files.
TEST(ServerConfig, InsecureDropsTheSecurityDirectoryFromTheSession) {
  const std::string path = ::testing::TempDir() + "/server_insecure.yaml";
  std::ofstream(path) << "security_dir: /etc/ccm-slam-dds/security\ninsecure: true\n";
  ServerConfig c;
  std::string error;
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_TRUE(c.insecure);
  rt::SessionOptions session;
  ASSERT_TRUE(rt::ResolveSession(c, &session, &error)) << error;
  EXPECT_TRUE(session.security_dir.empty());
  c.insecure = false;
  ASSERT_TRUE(rt::ResolveSession(c, &session, &error)) << error;
  EXPECT_EQ(session.security_dir, "/etc/ccm-slam-dds/security");
  std::ofstream(path) << "insecure: maybe\n";
  EXPECT_FALSE(LoadServerConfig(path, &c, &error));
  EXPECT_NE(error.find("insecure"), std::string::npos) << error;
}

}  // namespace
}  // namespace ccm::server
