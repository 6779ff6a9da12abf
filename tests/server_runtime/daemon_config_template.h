// The daemon config the ccm-server package installs (deploy/config/server-daemon.yaml.in) with
// its paths filled in as cmake/ccm_install_template.cmake does at install time. For tests;
// needs CCM_SOURCE_DIR.
#pragma once

#include <fstream>
#include <sstream>
#include <string>

namespace ccm::testing {

inline void ReplaceAll(std::string* text, const std::string& from, const std::string& to) {
  for (auto at = text->find(from); at != std::string::npos; at = text->find(from, at + to.size())) {
    text->replace(at, from.size(), to);
  }
}

/// Empty if the template cannot be read. `confdir` stands for @CCM_CONFDIR@; a non-empty
/// `state_dir` replaces /var/lib/ccm-slam-dds (the map file's folder).
inline std::string InstalledDaemonConfig(const std::string& confdir, const std::string& state_dir = "") {
  std::ifstream in(std::string(CCM_SOURCE_DIR) + "/deploy/config/server-daemon.yaml.in");
  if (!in) return "";
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  ReplaceAll(&yaml, "@CCM_CONFDIR@", confdir);
  if (!state_dir.empty()) ReplaceAll(&yaml, "/var/lib/ccm-slam-dds", state_dir);
  return yaml;
}

}  // namespace ccm::testing
