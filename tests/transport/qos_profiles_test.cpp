// Every shipped QoS file must load in the Fast DDS 2.9 parser and every profile in it must
// create its entity. Each file is checked in its own process (ccm_qos_check): Fast DDS
// keeps profiles process-wide and the files share profile names.
#include <gtest/gtest.h>

#include <filesystem>

#include "runtime_common/topics.h"
#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

// secure.xml is not a QoS file of its own (only the security plugins, added to another file's
// participant; its participant needs certificates): secure_wire_test.cpp loads and uses it.
constexpr const char* kSecurityPluginsFile = "secure.xml";

std::vector<std::string> ShippedQosFiles() {
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(CCM_QOS_DIR)) {
    if (entry.path().extension() == ".xml" && entry.path().filename() != kSecurityPluginsFile) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(QosProfiles, DefaultAndWifiAreShipped) {
  const auto files = ShippedQosFiles();
  auto has = [&](const std::string& name) {
    return std::any_of(files.begin(), files.end(), [&](const std::string& f) {
      return std::filesystem::path(f).filename() == name;
    });
  };
  EXPECT_TRUE(has("default.xml"));
  EXPECT_TRUE(has("wifi.xml"));
  EXPECT_TRUE(std::filesystem::exists(std::string(CCM_QOS_DIR) + "/" + kSecurityPluginsFile));
}

TEST(QosProfiles, EveryShippedFileCreatesEveryProfile) {
  int domain = 150;
  for (const auto& file : ShippedQosFiles()) {
    const auto results = testing::RunConcurrently(
        {{CCM_QOS_CHECK, file, "--domain", std::to_string(domain++)}},
        ::testing::TempDir() + "/qos_check", std::chrono::seconds(60));
    EXPECT_EQ(results[0].exit_code, 0) << file << ":\n" << results[0].output;
    // The profiles the runtimes select by name must all be present.
    for (const char* profile : {rt::kProfileParticipant, rt::kProfileNewDataWriter, rt::kProfileNewDataReader,
                                rt::kProfileUpdateWriter, rt::kProfileUpdateReader, rt::kProfileStatusWriter,
                                rt::kProfileStatusReader, rt::kProfileServerWriter, rt::kProfileServerAckWriter,
                                rt::kProfileServerReader,
                                rt::kProfileServerStatusWriter, rt::kProfileServerStatusReader,
                                rt::kProfileRos2Writer, rt::kProfileRos2Reader, rt::kProfileRos2CameraReader,
                                rt::kProfileRos2Participant}) {
      EXPECT_NE(results[0].output.find(std::string(profile) + "\n"), std::string::npos)
          << file << " lacks profile " << profile << ":\n" << results[0].output;
    }
    EXPECT_EQ(results[0].output.find("FAIL"), std::string::npos) << results[0].output;
  }
}

TEST(QosProfiles, BrokenFileIsRejectedWithAClearError) {
  const std::string path = ::testing::TempDir() + "/broken_qos.xml";
  std::ofstream(path) << "<dds xmlns=\"http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles\"><profiles>"
                         "<participant profile_name=\"p\"><rtps><no_such_element/></rtps></participant>"
                         "</profiles></dds>\n";
  const auto results = testing::RunConcurrently({{CCM_QOS_CHECK, path}}, ::testing::TempDir() + "/qos_broken",
                                                std::chrono::seconds(30));
  EXPECT_NE(results[0].exit_code, 0);
  EXPECT_NE(results[0].output.find("rejected"), std::string::npos) << results[0].output;
  const auto missing = testing::RunConcurrently({{CCM_QOS_CHECK, "/nonexistent/qos.xml"}},
                                                ::testing::TempDir() + "/qos_missing", std::chrono::seconds(30));
  EXPECT_NE(missing[0].exit_code, 0);
  EXPECT_NE(missing[0].output.find("does not exist"), std::string::npos) << missing[0].output;
}

}  // namespace
}  // namespace ccm
