#include "server_runtime/server_config.h"

#include <gtest/gtest.h>

#include <fstream>

namespace ccm::server {
namespace {

TEST(ServerConfig, LoadsAndValidates) {
  const std::string path = ::testing::TempDir() + "/server.yaml";
  std::ofstream(path) << "publish_rate_hz: 0.5\nack_repeats: 4\n";
  ServerConfig c;
  std::string error;
  ASSERT_TRUE(LoadServerConfig(path, &c, &error)) << error;
  EXPECT_DOUBLE_EQ(c.publish_rate_hz, 0.5);
  EXPECT_EQ(c.ack_repeats, 4);

  const std::string bad = ::testing::TempDir() + "/server_bad.yaml";
  std::ofstream(bad) << "ack_repeats: 0\n";
  EXPECT_FALSE(LoadServerConfig(bad, &c, &error));
  EXPECT_NE(error.find("ack_repeats"), std::string::npos) << error;
}

}  // namespace
}  // namespace ccm::server
