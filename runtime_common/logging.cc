#include "runtime_common/logging.h"

#include <fastdds/dds/log/Log.hpp>
#include <spdlog/pattern_formatter.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>

namespace ccm::rt {
namespace {

// sd-daemon(3) priority prefix ("<6>" info, "<4>" warning, ...): journald strips it and
// stores the line with that priority, so `journalctl -p warning` filters our logs.
class JournalPriorityFlag : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    const char* prefix = JournalPriorityPrefix(msg.level);
    dest.append(prefix, prefix + 3);
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<JournalPriorityFlag>(); }
};

// Fast DDS 2.9 turns a writer's legacy <throughputController> (the only bandwidth limit its
// XML parser knows) into a flow controller named after the participant's GUID. The second
// writer of a participant that sets one (keyframes and map points share the new-data
// profile) finds that name taken, logs this as an error and then uses the existing
// controller: one budget per participant, as qos_profiles/*.xml intend. Not an error for us.
bool IsSharedThroughputControllerNotice(const std::string& message) {
  return message.rfind("Error registering FlowController ", 0) == 0 &&
         message.find("|0.0.1.c1. Already registered") != std::string::npos;
}

// Fast DDS' own messages (discovery problems, XML errors) through spdlog: same format, one
// line each, and no colour codes, which Fast DDS' console consumer writes even to files and
// the journal. Called on Fast DDS' logging thread; spdlog's default logger is thread-safe.
class FastDdsToSpdlog : public eprosima::fastdds::dds::LogConsumer {
 public:
  void Consume(const eprosima::fastdds::dds::Log::Entry& entry) override {
    using Kind = eprosima::fastdds::dds::Log::Kind;
    auto level = entry.kind == Kind::Error     ? spdlog::level::err
                 : entry.kind == Kind::Warning ? spdlog::level::warn
                                               : spdlog::level::debug;
    if (IsSharedThroughputControllerNotice(entry.message)) level = spdlog::level::debug;
    spdlog::log(level, "Fast DDS [{}] {}", entry.context.category ? entry.context.category : "", entry.message);
  }
};

}  // namespace

const char* JournalPriorityPrefix(spdlog::level::level_enum level) {
  switch (level) {
    case spdlog::level::critical: return "<2>";
    case spdlog::level::err: return "<3>";
    case spdlog::level::warn: return "<4>";
    case spdlog::level::info: return "<6>";
    default: return "<7>";
  }
}

bool StdoutIsJournal() {
  // systemd sets JOURNAL_STREAM=<device>:<inode> of the stream it connected; it is only ours
  // if stdout is still that stream (not redirected by a wrapper script).
  const char* env = std::getenv("JOURNAL_STREAM");
  if (env == nullptr) return false;
  unsigned long long device = 0, inode = 0;
  if (std::sscanf(env, "%llu:%llu", &device, &inode) != 2) return false;
  struct stat st {};
  if (fstat(STDOUT_FILENO, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == device && static_cast<unsigned long long>(st.st_ino) == inode;
}

bool SetupLogging(const std::string& level, std::string* error) {
  const spdlog::level::level_enum parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    *error = "unknown log level '" + level + "' (trace, debug, info, warn, error, critical, off)";
    return false;
  }
  spdlog::set_level(parsed);
  eprosima::fastdds::dds::Log::ClearConsumers();
  eprosima::fastdds::dds::Log::RegisterConsumer(std::make_unique<FastDdsToSpdlog>());
  if (StdoutIsJournal()) {
    // journald time-stamps each line itself and shows the priority; no colour either.
    auto formatter = std::make_unique<spdlog::pattern_formatter>();
    formatter->add_flag<JournalPriorityFlag>('*').set_pattern("%*%v");
    spdlog::set_formatter(std::move(formatter));
  } else {
    // The default sink colours the level only on a terminal (spdlog checks isatty), so
    // files and pipes get plain text, one line per event.
    spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  }
  return true;
}

}  // namespace ccm::rt
