#include "runtime_common/logging.h"

namespace ccm::rt {

bool SetupLogging(const std::string& level, std::string* error) {
  const spdlog::level::level_enum parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    *error = "unknown log level '" + level + "' (trace, debug, info, warn, error, critical, off)";
    return false;
  }
  spdlog::set_level(parsed);
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  return true;
}

}  // namespace ccm::rt
