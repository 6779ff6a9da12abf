#include "server_runtime/prometheus_metrics.h"

namespace ccm::server {
namespace {

using Families = rt::PrometheusText;
using Labels = rt::PrometheusText::Labels;

// Adds `name` when `object[key]` is a number or a boolean; absent fields are left out.
void AddIf(Families* f, const nlohmann::json& object, const char* key, const std::string& name, const char* type,
           const char* help, const Labels& labels = {}) {
  if (!object.is_object() || !object.contains(key)) return;
  const nlohmann::json& v = object[key];
  if (v.is_boolean()) {
    f->Add(name, type, help, labels, v.get<bool>() ? 1.0 : 0.0);
  } else if (v.is_number()) {
    f->Add(name, type, help, labels, v.get<double>());
  }
}

void AddTotals(Families* f, const nlohmann::json& status) {
  const nlohmann::json totals = status.value("totals", nlohmann::json::object());
  AddIf(f, totals, "agents", "ccm_server_agents", "gauge", "Agents the server has heard from.");
  AddIf(f, totals, "maps", "ccm_server_maps", "gauge", "Server maps (one per agent until fused).");
  AddIf(f, totals, "keyframes", "ccm_server_keyframes", "gauge", "Keyframes in all server maps.");
  AddIf(f, totals, "map_points", "ccm_server_map_points", "gauge", "Map points in all server maps.");
  AddIf(f, totals, "fusions", "ccm_server_fusions_total", "counter", "Map fusions accepted.");
  AddIf(f, totals, "loops", "ccm_server_loops_total", "counter", "Loop closures accepted.");
  AddIf(f, totals, "global_bas", "ccm_server_global_bas_total", "counter", "Global bundle adjustments applied.");
  AddIf(f, totals, "global_ba_seconds", "ccm_server_global_ba_seconds_total", "counter",
        "Wall time of the applied global bundle adjustments.");
  AddIf(f, totals, "keyframes_removed", "ccm_server_keyframes_removed_total", "counter",
        "Keyframes removed as redundant.");
  const nlohmann::json queues = status.value("queues", nlohmann::json::object());
  AddIf(f, queues, "place_recognition", "ccm_server_place_recognition_queue_keyframes", "gauge",
        "Keyframes waiting for place recognition.");
  AddIf(f, queues, "global_ba_pending", "ccm_server_global_ba_pending_maps", "gauge",
        "Maps waiting for a global bundle adjustment.");
  AddIf(f, queues, "global_ba_running", "ccm_server_global_ba_running", "gauge",
        "1 while a global bundle adjustment runs.");
}

void AddAgent(Families* f, const nlohmann::json& a) {
  if (!a.is_object() || !a.contains("id") || !a["id"].is_number()) return;
  Labels l = {{"agent", std::to_string(a["id"].get<int64_t>())}};
  if (a.contains("name") && a["name"].is_string()) l.push_back({"name", a["name"].get<std::string>()});
  AddIf(f, a, "queue", "ccm_server_agent_queue_batches", "gauge", "Batches of the agent waiting for registration.", l);
  AddIf(f, a, "queue_bytes", "ccm_server_agent_queue_bytes", "gauge",
        "Approximate size of the agent's batches waiting for registration.", l);
  AddIf(f, a, "lag_s", "ccm_server_agent_registration_lag_seconds", "gauge",
        "How long the agent's oldest waiting batch has waited (0: queue empty).", l);
  AddIf(f, a, "registered", "ccm_server_agent_keyframes_registered_total", "counter",
        "The agent's keyframes registered in a server map.", l);
  AddIf(f, a, "duplicates", "ccm_server_agent_keyframes_duplicate_total", "counter",
        "The agent's keyframes kept as pose anchors only (near-duplicates).", l);
  AddIf(f, a, "rejected", "ccm_server_agent_items_rejected_total", "counter",
        "The agent's keyframes, points and updates that failed validation.", l);
  AddIf(f, a, "batches_dropped", "ccm_server_agent_batches_dropped_total", "counter",
        "The agent's batches dropped (queue budget full).", l);
  AddIf(f, a, "keyframes", "ccm_server_agent_keyframes", "gauge", "The agent's keyframes in the server maps.", l);
  AddIf(f, a, "segments", "ccm_server_agent_segments", "gauge", "The agent's VO segments the server knows.", l);
  AddIf(f, a, "alive", "ccm_server_agent_alive", "gauge", "1 while the agent's heartbeat arrives.", l);
  AddIf(f, a, "last_seen_s", "ccm_server_agent_last_seen_seconds", "gauge",
        "Seconds since the server started at which the agent was last heard.", l);
  AddIf(f, a, "kfs_sent", "ccm_server_agent_keyframes_sent_total", "counter",
        "Keyframes the agent reports having sent.", l);
  AddIf(f, a, "kfs_acked", "ccm_server_agent_keyframes_acked_total", "counter",
        "Keyframes the agent reports acknowledged.", l);
  AddIf(f, a, "kfs_lost", "ccm_server_agent_keyframes_lost_total", "counter",
        "Keyframes the agent reports lost (dropped unacknowledged).", l);
  if (a.contains("tracking") && a["tracking"].is_string()) {
    for (const char* state : {"initializing", "tracking", "lost", "unknown"}) {
      Labels s = l;
      s.push_back({"state", state});
      f->Add("ccm_server_agent_tracking_state", "gauge", "The agent's tracking state from its heartbeat (1: current).",
             s, a["tracking"].get<std::string>() == state ? 1.0 : 0.0);
    }
  }
}

void AddHost(Families* f, const nlohmann::json& host) {
  if (!host.is_object()) return;
  AddIf(f, host, "elapsed_s", "ccm_server_uptime_seconds", "gauge", "Seconds since the server started.");
  AddIf(f, host, "rejected", "ccm_server_messages_rejected_total", "counter", "Messages refused by validation.");
  AddIf(f, host, "refused_agents", "ccm_server_agents_refused_total", "counter",
        "Messages from agents beyond max_agents.");
  AddIf(f, host, "autosave_age_s", "ccm_server_autosave_age_seconds", "gauge",
        "Seconds since the map file was last written or found unchanged (-1: never).");
  AddIf(f, host, "autosave_failures", "ccm_server_autosave_failures_total", "counter", "Autosaves that failed.");
  if (!host.contains("traffic") || !host["traffic"].is_array()) return;
  for (const nlohmann::json& t : host["traffic"]) {
    if (!t.is_object() || !t.contains("topic") || !t.contains("direction")) continue;
    const Labels l = {{"topic", t["topic"].get<std::string>()}, {"direction", t["direction"].get<std::string>()}};
    AddIf(f, t, "samples", "ccm_server_dds_samples_total", "counter", "DDS samples per topic and direction.", l);
    AddIf(f, t, "bytes", "ccm_server_dds_payload_bytes_total", "counter",
          "Serialized payload bytes per topic and direction.", l);
    AddIf(f, t, "lost", "ccm_server_dds_samples_lost_total", "counter", "Samples DDS reported lost.", l);
    AddIf(f, t, "queue_dropped", "ccm_server_dds_queue_dropped_total", "counter",
          "Samples dropped by a full intake queue.", l);
  }
}

void AddHttp(Families* f, const nlohmann::json& http) {
  AddIf(f, http, "requests", "ccm_server_http_requests_total", "counter", "HTTP requests answered (map view and API).");
  AddIf(f, http, "errors", "ccm_server_http_errors_total", "counter", "HTTP requests answered with a 4xx or 5xx.");
  AddIf(f, http, "metrics_requests", "ccm_server_metrics_scrapes_total", "counter", "Requests of /metrics.");
}

}  // namespace

std::string ServerMetricsText(const nlohmann::json& status) {
  Families f;
  AddTotals(&f, status);
  if (status.contains("agents") && status["agents"].is_array()) {
    for (const nlohmann::json& a : status["agents"]) AddAgent(&f, a);
  }
  AddHost(&f, status.value("host", nlohmann::json::object()));
  AddHttp(&f, status.value("http", nlohmann::json::object()));
  return f.Text();
}

}  // namespace ccm::server
