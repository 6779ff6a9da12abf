// The summary a ccm_* process prints last: its final line that is a JSON object (earlier
// lines are logs). A discarded json (is_discarded()) when there is none.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace ccm::testing {

inline nlohmann::json LastJsonLine(const std::string& output) {
  const auto start = output.rfind("\n{");
  return nlohmann::json::parse(output.substr(start == std::string::npos ? 0 : start + 1), nullptr, false);
}

}  // namespace ccm::testing
