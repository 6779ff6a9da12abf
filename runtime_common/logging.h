// Logging setup for the runtimes (spdlog). slam_core never logs by itself; the runtimes
// pass it sinks where it needs one. One line per event; under systemd (stdout connected to
// the journal) lines carry an sd-daemon priority prefix instead of a time stamp.
#pragma once

#include <spdlog/spdlog.h>

#include <string>

namespace ccm::rt {

/// Sets the default logger's level ("trace".."off") and pattern; false for an unknown level.
bool SetupLogging(const std::string& level, std::string* error);
/// True when stdout is the journald stream systemd gave this process ($JOURNAL_STREAM).
bool StdoutIsJournal();
/// "<N>" sd-daemon(3) priority of a level (3 characters).
const char* JournalPriorityPrefix(spdlog::level::level_enum level);

}  // namespace ccm::rt
