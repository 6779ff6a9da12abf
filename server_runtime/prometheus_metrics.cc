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

// A status field and the metric it becomes.
struct Field {
  const char* key;
  const char* name;
  const char* type;
  const char* help;
};

constexpr Field kTotals[] = {
    {"agents", "ccm_server_agents", "gauge", "Agents the server has heard from."},
    {"maps", "ccm_server_maps", "gauge", "Server maps (one per agent until fused)."},
    {"keyframes", "ccm_server_keyframes", "gauge", "Keyframes in all server maps."},
    {"map_points", "ccm_server_map_points", "gauge", "Map points in all server maps."},
    {"fusions", "ccm_server_fusions_total", "counter", "Map fusions accepted."},
    {"loops", "ccm_server_loops_total", "counter", "Loop closures accepted."},
    {"global_bas", "ccm_server_global_bas_total", "counter", "Global bundle adjustments applied."},
    {"global_ba_seconds", "ccm_server_global_ba_seconds_total", "counter",
     "Wall time of the applied global bundle adjustments."},
    {"keyframes_removed", "ccm_server_keyframes_removed_total", "counter", "Keyframes removed as redundant."},
};
constexpr Field kQueues[] = {
    {"place_recognition", "ccm_server_place_recognition_queue_keyframes", "gauge",
     "Keyframes waiting for place recognition."},
    {"global_ba_pending", "ccm_server_global_ba_pending_maps", "gauge", "Maps waiting for a global bundle adjustment."},
    {"global_ba_running", "ccm_server_global_ba_running", "gauge", "1 while a global bundle adjustment runs."},
};
constexpr Field kAgent[] = {
    {"queue", "ccm_server_agent_queue_batches", "gauge", "Batches of the agent waiting for registration."},
    {"queue_bytes", "ccm_server_agent_queue_bytes", "gauge",
     "Approximate size of the agent's batches waiting for registration."},
    {"lag_s", "ccm_server_agent_registration_lag_seconds", "gauge",
     "Age of the agent's oldest batch not yet registered (0: queue empty)."},
    {"registered", "ccm_server_agent_keyframes_registered_total", "counter",
     "The agent's keyframes registered in a server map."},
    {"duplicates", "ccm_server_agent_keyframes_duplicate_total", "counter",
     "The agent's keyframes kept as pose anchors only (near-duplicates)."},
    {"rejected", "ccm_server_agent_items_rejected_total", "counter",
     "The agent's keyframes, points and updates that failed validation."},
    {"batches_dropped", "ccm_server_agent_batches_dropped_total", "counter",
     "The agent's batches dropped (queue budget full)."},
    {"keyframes", "ccm_server_agent_keyframes", "gauge", "The agent's keyframes in the server maps."},
    {"segments", "ccm_server_agent_segments", "gauge", "The agent's VO segments the server knows."},
    {"alive", "ccm_server_agent_alive", "gauge", "1 while the agent's heartbeat arrives."},
    {"last_seen_s", "ccm_server_agent_last_seen_seconds", "gauge",
     "Seconds since the server started at which the agent was last heard."},
    {"kfs_sent", "ccm_server_agent_keyframes_sent_total", "counter", "Keyframes the agent reports having sent."},
    {"kfs_acked", "ccm_server_agent_keyframes_acked_total", "counter", "Keyframes the agent reports acknowledged."},
    {"kfs_lost", "ccm_server_agent_keyframes_lost_total", "counter",
     "Keyframes the agent reports lost (dropped unacknowledged)."},
};
constexpr Field kHost[] = {
    {"elapsed_s", "ccm_server_uptime_seconds", "gauge", "Seconds since the server started."},
    {"rejected", "ccm_server_messages_rejected_total", "counter", "Messages refused by validation."},
    {"refused_agents", "ccm_server_agents_refused_total", "counter", "Messages from agents beyond max_agents."},
    {"autosave_age_s", "ccm_server_autosave_age_seconds", "gauge",
     "Seconds since the map file was last written or found unchanged (-1: never)."},
    {"autosave_failures", "ccm_server_autosave_failures_total", "counter", "Autosaves that failed."},
};
constexpr Field kTraffic[] = {
    {"samples", "ccm_server_dds_samples_total", "counter", "DDS samples per topic and direction."},
    {"bytes", "ccm_server_dds_payload_bytes_total", "counter", "Serialized payload bytes per topic and direction."},
    {"lost", "ccm_server_dds_samples_lost_total", "counter", "Samples DDS reported lost."},
    {"queue_dropped", "ccm_server_dds_queue_dropped_total", "counter", "Samples dropped by a full intake queue."},
};
constexpr Field kHttp[] = {
    {"requests", "ccm_server_http_requests_total", "counter", "HTTP requests answered (map view and API)."},
    {"errors", "ccm_server_http_errors_total", "counter", "HTTP requests answered with a 4xx or 5xx."},
    {"metrics_requests", "ccm_server_metrics_scrapes_total", "counter", "Requests of /metrics."},
};

template <size_t N>
void AddFields(Families* f, const nlohmann::json& object, const Field (&fields)[N], const Labels& labels = {}) {
  for (const Field& field : fields) AddIf(f, object, field.key, field.name, field.type, field.help, labels);
}

nlohmann::json Member(const nlohmann::json& status, const char* key) {
  return status.is_object() ? status.value(key, nlohmann::json::object()) : nlohmann::json::object();
}

void AddAgent(Families* f, const nlohmann::json& a) {
  if (!a.is_object() || !a.contains("id") || !a["id"].is_number()) return;
  Labels l = {{"agent", std::to_string(a["id"].get<int64_t>())}};
  if (a.contains("name") && a["name"].is_string()) l.push_back({"name", a["name"].get<std::string>()});
  AddFields(f, a, kAgent, l);
  if (!a.contains("tracking") || !a["tracking"].is_string()) return;
  for (const char* state : {"initializing", "tracking", "lost", "unknown"}) {
    Labels s = l;
    s.push_back({"state", state});
    f->Add("ccm_server_agent_tracking_state", "gauge", "The agent's tracking state from its heartbeat (1: current).", s,
           a["tracking"].get<std::string>() == state ? 1.0 : 0.0);
  }
}

void AddHost(Families* f, const nlohmann::json& host) {
  AddFields(f, host, kHost);
  if (!host.contains("traffic") || !host["traffic"].is_array()) return;
  for (const nlohmann::json& t : host["traffic"]) {
    if (!t.is_object() || !t.contains("topic") || !t["topic"].is_string() || !t.contains("direction") ||
        !t["direction"].is_string()) {
      continue;
    }
    AddFields(f, t, kTraffic, {{"topic", t["topic"].get<std::string>()}, {"direction", t["direction"].get<std::string>()}});
  }
}

}  // namespace

std::string ServerMetricsText(const nlohmann::json& status) {
  Families f;
  AddFields(&f, Member(status, "totals"), kTotals);
  AddFields(&f, Member(status, "queues"), kQueues);
  if (status.contains("agents") && status["agents"].is_array()) {
    for (const nlohmann::json& a : status["agents"]) AddAgent(&f, a);
  }
  AddHost(&f, Member(status, "host"));
  AddFields(&f, Member(status, "http"), kHttp);
  return f.Text();
}

}  // namespace ccm::server
