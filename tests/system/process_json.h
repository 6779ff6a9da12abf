// The summary a ccm_* process prints last (its final line that is a JSON object; earlier
// lines are logs), and the JSON files they write. A discarded or null json when there is none.
#pragma once

#include <nlohmann/json.hpp>

#include <fstream>
#include <string>

namespace ccm::testing {

inline nlohmann::json LastJsonLine(const std::string& output) {
  const auto start = output.rfind("\n{");
  return nlohmann::json::parse(output.substr(start == std::string::npos ? 0 : start + 1), nullptr, false);
}

inline nlohmann::json ReadJsonFile(const std::string& path) {
  std::ifstream in(path);
  return in ? nlohmann::json::parse(in, nullptr, false) : nlohmann::json();
}

}  // namespace ccm::testing
