#include "agent_runtime/agent_metrics.h"

#ifdef CCM_AGENT_HTTP
#include <httplib.h>
#endif

#include "runtime_common/prometheus_text.h"

namespace ccm::agent {
namespace {

// A comm counter and the metric it becomes.
struct LinkField {
  const char* name;
  const char* type;
  const char* help;
  std::uint64_t AgentCommStats::*value;
};

constexpr LinkField kLinkFields[] = {
    {"ccm_agent_keyframes_sent_total", "counter", "Keyframes sent (first transmissions).", &AgentCommStats::kfs_sent},
    {"ccm_agent_keyframes_resent_total", "counter", "Keyframes sent again (gap, timeout, server restart).",
     &AgentCommStats::kfs_resent},
    {"ccm_agent_keyframes_acked_total", "counter", "Keyframes the server acknowledged.", &AgentCommStats::kfs_acked},
    {"ccm_agent_keyframes_unacked", "gauge", "Keyframes sent and not acknowledged yet.", &AgentCommStats::kfs_unacked},
    {"ccm_agent_keyframes_unpersisted", "gauge", "Keyframes acknowledged but not yet in the server's map file.",
     &AgentCommStats::kfs_unpersisted},
    {"ccm_agent_map_points_sent_total", "counter", "Map points sent.", &AgentCommStats::mps_sent},
    {"ccm_agent_backlog_bytes", "gauge", "Packed data waiting for the rate limit.", &AgentCommStats::backlog_bytes},
    {"ccm_agent_deferred_items", "gauge", "Keyframes and points held back for new_keyframe_delay_s.",
     &AgentCommStats::deferred},
    {"ccm_agent_write_failures_total", "counter", "DDS writes that failed.", &AgentCommStats::write_failures},
    {"ccm_agent_server_messages_total", "counter", "Messages from the server.", &AgentCommStats::server_msgs},
    {"ccm_agent_server_messages_rejected_total", "counter", "Server messages refused by validation.",
     &AgentCommStats::server_msgs_rejected},
    {"ccm_agent_server_keyframes_received_total", "counter", "Keyframes the server shared back.",
     &AgentCommStats::server_keyframes_received},
    {"ccm_agent_server_restarts_total", "counter", "Server restarts seen (new epochs).", &AgentCommStats::server_restarts},
};

}  // namespace

std::string AgentMetricsText(int agent_id, const FlightGauges& g, const AgentCommStats* comm) {
  rt::PrometheusText t;
  const rt::PrometheusText::Labels l = {{"agent", std::to_string(agent_id)}};
  t.Add("ccm_agent_frames_total", "counter", "Camera frames processed.", l, static_cast<double>(g.frames.load()));
  t.Add("ccm_agent_frames_tracked_total", "counter", "Frames with a pose.", l, static_cast<double>(g.tracked.load()));
  t.Add("ccm_agent_frames_skipped_total", "counter",
        "Frames a live camera delivered while tracking was busy, skipped (not processed).", l,
        static_cast<double>(g.frames_skipped.load()));
  t.Add("ccm_agent_keyframes_created_total", "counter", "Keyframes the VO made.", l,
        static_cast<double>(g.keyframes_created.load()));
  t.Add("ccm_agent_segments", "gauge", "VO map segments opened (a new one after relocalization failed).", l,
        static_cast<double>(g.segments.load()));
  const int state = g.state.load();
  for (const auto& [value, name] : {std::pair{0, "initializing"}, std::pair{1, "tracking"}, std::pair{2, "lost"}}) {
    rt::PrometheusText::Labels s = l;
    s.push_back({"state", name});
    t.Add("ccm_agent_tracking_state", "gauge", "Tracking state (1: current).", s, state == value ? 1.0 : 0.0);
  }
  if (!comm) return t.Text();
  for (const LinkField& field : kLinkFields) {
    t.Add(field.name, field.type, field.help, l, static_cast<double>(comm->*field.value));
  }
  return t.Text();
}

std::unique_ptr<MetricsEndpoint> MetricsEndpoint::Start(const std::string& bind, int port,
                                                        std::function<std::string()> render, std::string* error) {
#ifdef CCM_AGENT_HTTP
  std::unique_ptr<MetricsEndpoint> e(new MetricsEndpoint());
  e->http_ = std::make_unique<httplib::Server>();
  e->http_->new_task_queue = [] { return new httplib::ThreadPool(1); };
  e->http_->set_payload_max_length(4096);
  // SO_REUSEADDR only (httplib's default adds SO_REUSEPORT): a port in use is an error.
  e->http_->set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  e->http_->Get("/metrics", [render = std::move(render)](const httplib::Request&, httplib::Response& res) {
    res.set_content(render(), rt::kPrometheusContentType);
    res.set_header("Cache-Control", "no-store");
  });
  e->port_ = port == 0 ? e->http_->bind_to_any_port(bind) : (e->http_->bind_to_port(bind, port) ? port : -1);
  if (e->port_ < 0) {
    *error = "--metrics: cannot listen on " + bind + ":" + std::to_string(port) + " (address in use or not local?)";
    return nullptr;
  }
  e->thread_ = std::thread([s = e->http_.get()] { s->listen_after_bind(); });
  return e;
#else
  (void)bind;
  (void)port;
  (void)render;
  *error = "--metrics: this ccm_agent was built without cpp-httplib (libcpp-httplib-dev)";
  return nullptr;
#endif
}

MetricsEndpoint::~MetricsEndpoint() { Stop(); }

void MetricsEndpoint::Stop() {
#ifdef CCM_AGENT_HTTP
  if (http_) http_->stop();
#endif
  if (thread_.joinable()) thread_.join();
}

}  // namespace ccm::agent
