// Where a binary finds its data (QoS profiles, the vocabulary): first beside its own
// install location, <bindir>/../share/ccm-slam-dds/<relative> (so /usr, /usr/local, /opt or
// a `dpkg -x` tree all work without configuration), then the source/build tree it was built
// from (running from the build directory). Header-only, no DDS: the DDS-free tools use it too.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace ccm::rt {

inline constexpr const char* kInstallDataSubdir = "share/ccm-slam-dds";
/// The vocabulary `cmake --install` ships, relative to the data dir (the general default,
/// docs/place-recognition.md; sites may train their own): the default of ccm_server, ccm_agent
/// and ccm_replay.
inline constexpr const char* kInstalledVocabulary = "vocabulary/default_vocab_k10_l5.ccmvoc";

/// <dir of this executable>/../share/ccm-slam-dds, or "" if /proc/self/exe is unreadable.
inline std::string InstalledDataDir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  return (exe.parent_path().parent_path() / kInstallDataSubdir).string();
}

/// The installed copy of `relative` if it exists, else `build_tree_path` (may be "").
inline std::string FindDataFile(const std::string& relative, const std::string& build_tree_path) {
  const std::string dir = InstalledDataDir();
  std::error_code ec;
  if (!dir.empty() && std::filesystem::exists(std::filesystem::path(dir) / relative, ec)) {
    return (std::filesystem::path(dir) / relative).string();
  }
  return build_tree_path;
}

}  // namespace ccm::rt
