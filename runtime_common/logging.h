// Logging setup for the runtimes (spdlog). slam_core never logs by itself; the runtimes
// pass it sinks where it needs one.
#pragma once

#include <spdlog/spdlog.h>

#include <string>

namespace ccm::rt {

/// Sets the default logger's level ("trace".."off") and pattern; false for an unknown level.
bool SetupLogging(const std::string& level, std::string* error);

}  // namespace ccm::rt
