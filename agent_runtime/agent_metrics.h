// ccm_agent --metrics PORT (issue 32): the agent's state for Prometheus, opt-in. The tracking
// thread keeps a few atomic gauges (FlightGauges); a scrape renders them with the comm
// module's counters (AgentComm::Stats(), which takes the comm's stats lock only). The HTTP
// endpoint (cpp-httplib, one accept thread of its own, owned and joined by RunAgent) serves
// GET /metrics and nothing else; bound to 127.0.0.1 unless --metrics-bind says more.
// Built only where cpp-httplib is found (CCM_AGENT_HTTP); elsewhere --metrics says so.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "agent_runtime/agent_comm.h"

namespace httplib {
class Server;
}

namespace ccm::agent {

/// Written by the tracking thread once per frame, read by scrapes.
struct FlightGauges {
  std::atomic<int64_t> frames{0};
  std::atomic<int64_t> tracked{0};           ///< frames with a pose
  std::atomic<int64_t> frames_skipped{0};    ///< a live camera's frames skipped while tracking was busy
  std::atomic<int64_t> keyframes_created{0};
  std::atomic<int64_t> segments{1};          ///< VO segments opened (1 + relocalization failures)
  std::atomic<int> state{-1};                ///< TrackingState, -1 before the first frame
};

/// The metrics text: `ccm_agent_` families, each sample labelled with the agent id. `comm`
/// null: standalone (no link families).
std::string AgentMetricsText(int agent_id, const FlightGauges& gauges, const AgentCommStats* comm);

class MetricsEndpoint {
 public:
  /// Serves `render()` at GET /metrics on bind:port (0: any free port). nullptr and *error
  /// when the port cannot be bound or this build has no HTTP library.
  static std::unique_ptr<MetricsEndpoint> Start(const std::string& bind, int port, std::function<std::string()> render,
                                                std::string* error);
  ~MetricsEndpoint();
  MetricsEndpoint(const MetricsEndpoint&) = delete;
  MetricsEndpoint& operator=(const MetricsEndpoint&) = delete;
  int port() const { return port_; }
  /// Stops serving and joins the thread. Idempotent.
  void Stop();

 private:
  MetricsEndpoint() = default;
  std::unique_ptr<httplib::Server> http_;
  std::thread thread_;
  int port_ = -1;
};

}  // namespace ccm::agent
