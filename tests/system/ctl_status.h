// A live server watched the way an operator does: `ccm_ctl status --json` over wifi.xml
// (the ccm/server_status topic). Shared by the daemon and chaos tests.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <string>
#include <thread>

#include "tests/transport/subprocess.h"

namespace ccm::testing {

inline std::string WifiQos() { return std::string(CCM_QOS_DIR) + "/wifi.xml"; }

/// One status of the server on `domain`; not an object when no server answered.
inline nlohmann::json CtlStatus(const std::string& dir, int domain) {
  const auto r = RunConcurrently(
      {{CCM_CTL, "status", "--json", "--domain", std::to_string(domain), "--qos", WifiQos(), "--timeout", "4"}},
      dir + "/ctl", std::chrono::seconds(20));
  if (r[0].exit_code != 0) return nlohmann::json();
  return nlohmann::json::parse(r[0].output.substr(r[0].output.find('{')), nullptr, false);
}

inline const nlohmann::json* StatusAgent(const nlohmann::json& status, int id) {
  if (!status.is_object()) return nullptr;
  for (const auto& a : status["agents"]) {
    if (a["agent_id"].get<int>() == id) return &a;
  }
  return nullptr;
}

inline size_t StatusMapKeyframes(const nlohmann::json& status) {
  size_t n = 0;
  for (const auto& m : status["maps"]) n += m["keyframes"].get<size_t>();
  return n;
}

/// Polls the status until `done` holds (returns that status) or the deadline passes (returns
/// the last one).
template <typename Pred>
nlohmann::json WaitForCtlStatus(const std::string& dir, std::chrono::seconds timeout, Pred done, int domain) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  nlohmann::json last;
  while (std::chrono::steady_clock::now() < deadline) {
    last = CtlStatus(dir, domain);
    if (last.is_object() && done(last)) return last;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  return last;
}

}  // namespace ccm::testing
