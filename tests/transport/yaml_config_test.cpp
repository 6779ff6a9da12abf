// Strict YAML config reading: unknown keys, wrong types, missing files and syntax errors
// are all reported with the file and key.
#include <gtest/gtest.h>

#include <fstream>

#include "runtime_common/yaml_config.h"

namespace ccm {
namespace {

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

struct Demo {
  int agent_id = 0;
  double rate_hz = 2.0;
  std::string name = "x";
};

std::string Read(const std::string& path, Demo* demo) {
  std::string error;
  auto node = rt::YamlReader::LoadFile(path, &error);
  if (!node) return error;
  rt::YamlReader r(*node, path);
  r.Get("agent_id", &demo->agent_id);
  r.Get("rate_hz", &demo->rate_hz);
  r.Get("name", &demo->name);
  r.RejectUnknownKeys();
  return r.error();
}

TEST(YamlConfig, ReadsKnownKeysAndKeepsDefaults) {
  Demo d;
  EXPECT_EQ(Read(WriteFile("ok.yaml", "agent_id: 3\nname: drone\n"), &d), "");
  EXPECT_EQ(d.agent_id, 3);
  EXPECT_EQ(d.name, "drone");
  EXPECT_DOUBLE_EQ(d.rate_hz, 2.0);
}

TEST(YamlConfig, RejectsUnknownKey) {
  Demo d;
  const std::string error = Read(WriteFile("typo.yaml", "agent_id: 3\nrate_hx: 4\n"), &d);
  EXPECT_NE(error.find("rate_hx"), std::string::npos) << error;
  EXPECT_NE(error.find("not a known key"), std::string::npos) << error;
}

TEST(YamlConfig, RejectsWrongType) {
  Demo d;
  const std::string error = Read(WriteFile("type.yaml", "agent_id: three\n"), &d);
  EXPECT_NE(error.find("agent_id"), std::string::npos) << error;
  EXPECT_NE(error.find("integer"), std::string::npos) << error;
}

TEST(YamlConfig, ReportsMissingFileAndSyntaxError) {
  Demo d;
  EXPECT_NE(Read("/nonexistent/agent.yaml", &d).find("does not exist"), std::string::npos);
  const std::string error = Read(WriteFile("syntax.yaml", "agent_id: [1, 2\n"), &d);
  EXPECT_NE(error.find("line"), std::string::npos) << error;
}

}  // namespace
}  // namespace ccm
