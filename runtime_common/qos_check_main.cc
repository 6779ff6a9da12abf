// ccm_qos_check FILE: loads a Fast DDS XML profiles file and creates the entities of every
// named participant / data_writer / data_reader profile in it, so a typo or an element the
// 2.9 parser does not know is caught before deployment (the parser silently drops the
// whole file otherwise). Exit code 0 only if every profile produced an entity.
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/log/Log.hpp>

#include <CLI/CLI.hpp>

#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/logging.h"

namespace fdds = eprosima::fastdds::dds;

int main(int argc, char** argv) {
  std::string file;
  int domain = 0;
  CLI::App app{"ccm_qos_check: load a QoS XML file and create every profile's entities"};
  app.add_option("file", file, "Fast DDS XML profiles file")->required();
  app.add_option("--domain", domain, "DDS domain id for the probe entities")->check(CLI::Range(0, 232));
  CLI11_PARSE(app, argc, argv);

  std::string error;
  // Fast DDS' messages through our log consumer (plain lines, the same filtering as the
  // runtimes); Report() flushes them first so they never split a result line.
  if (!ccm::rt::SetupLogging("info", &error)) return 1;
  auto report = [](const std::string& line) {
    eprosima::fastdds::dds::Log::Flush();
    std::cout << line << std::endl;
  };
  if (!ccm::rt::LoadQosFile(file, &error)) {
    std::cerr << "error: " << error << "\n";
    return 1;
  }
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  const std::string xml = text.str();
  const std::regex profile_re(R"(<(participant|data_writer|data_reader)\s+profile_name=\"([^\"]+)\")");
  int failures = 0, checked = 0;
  std::vector<std::pair<std::string, std::string>> endpoints;
  std::vector<std::string> participant_profiles;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), profile_re); it != std::sregex_iterator(); ++it) {
    const std::string kind = (*it)[1], name = (*it)[2];
    if (kind == "participant") {
      participant_profiles.push_back(name);
    } else {
      endpoints.emplace_back(kind, name);
    }
  }
  if (participant_profiles.empty()) {
    std::cerr << "error: no participant profile in " << file << "\n";
    return 1;
  }
  // Every participant profile must create a participant (e.g. wifi.xml's discovery-server
  // client too); endpoints are checked on the first one.
  ccm::rt::SessionOptions options;
  options.qos_file = file;
  options.domain_id = domain;
  std::unique_ptr<ccm::rt::DdsSession> session;
  for (const std::string& profile : participant_profiles) {
    options.participant_profile = profile;
    auto created = ccm::rt::DdsSession::Create(options, &error);
    ++checked;
    if (!created) {
      std::cerr << "FAIL participant " << profile << ": " << error << "\n";
      return 1;
    }
    report("ok   participant  " + profile);
    if (!session) session = std::move(created);
  }
  fdds::TypeSupport type(new ccm::msg::KeyframeUpdatePubSubType());
  fdds::Topic* topic = session->GetTopic("ccm/qos_check", type, &error);
  for (const auto& [kind, name] : endpoints) {
    ++checked;
    bool ok = false;
    if (kind == "data_writer") {
      fdds::DataWriterQos qos;
      if (session->publisher()->get_datawriter_qos_from_profile(name, qos) == ReturnCode_t::RETCODE_OK) {
        fdds::DataWriter* w = session->publisher()->create_datawriter(topic, qos);
        ok = w != nullptr;
        if (ok) session->publisher()->delete_datawriter(w);
      }
    } else {
      fdds::DataReaderQos qos;
      if (session->subscriber()->get_datareader_qos_from_profile(name, qos) == ReturnCode_t::RETCODE_OK) {
        fdds::DataReader* r = session->subscriber()->create_datareader(topic, qos);
        ok = r != nullptr;
        if (ok) session->subscriber()->delete_datareader(r);
      }
    }
    report((ok ? "ok   " : "FAIL ") + kind + "  " + name);
    if (!ok) ++failures;
  }
  report(std::to_string(checked - failures) + " of " + std::to_string(checked) + " profiles usable in " + file);
  return failures == 0 ? 0 : 1;
}
