// ccm_server configuration: defaults, validation and strict YAML loading.
#pragma once

#include <string>

namespace ccm::server {

struct ServerConfig {
  int domain_id = 0;                 // DDS domain, 0..232
  std::string qos_file;              // empty: $FASTRTPS_DEFAULT_PROFILES_FILE or qos_profiles/default.xml
  std::string log_level = "info";
  double publish_rate_hz = 1.0;      // server -> agent messages per agent per second (< agent rate)
  int ack_repeats = 3;               // each ack is repeated in this many messages (they are BEST_EFFORT)
  int max_agents = 16;

  std::string Validate() const;
};

bool LoadServerConfig(const std::string& path, ServerConfig* config, std::string* error);

}  // namespace ccm::server
