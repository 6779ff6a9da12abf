// GET /metrics (issue 32): the ground station's status in Prometheus' text exposition format
// (version 0.0.4), for the monitoring operators already run. Rendered from the same status
// object /api/status answers with (map_view_status.cc, plus the host's facts), so the two
// never disagree. Names follow Prometheus' conventions: `ccm_server_` prefix, base units in
// the name (`_seconds`, `_bytes`), `_total` for counters, agents and topics as labels.
// docs/monitoring.md lists every metric, a scrape config and alert rules.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "runtime_common/prometheus_text.h"

namespace ccm::server {

using rt::kPrometheusContentType;

/// The metrics text for a status object as /api/status builds it. Fields the status lacks
/// (a replay has no DDS traffic, no autosave) are left out, never reported as 0.
std::string ServerMetricsText(const nlohmann::json& status);

}  // namespace ccm::server
