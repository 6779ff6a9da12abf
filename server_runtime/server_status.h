// The operator status of a running ccm_server (idl/ccm_status.idl): MakeServerStatus takes a
// snapshot of the back-end, the comm module and the traffic counters; StatusPublisher writes
// it on ccm/server_status. The daemon's main loop calls both every status_period_s: no
// thread of its own. ccm_ctl reads the topic (status_format.h prints it).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "idl/ccm_statusPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/typed_endpoints.h"
#include "server_runtime/server_comm.h"
#include "slam_core/server/server_backend.h"

namespace ccm::server {

/// What the daemon itself knows (not the back-end nor the comm module).
struct DaemonInfo {
  double uptime_s = 0.0;
  std::string map_file;       ///< where the map stack is saved ("" if nowhere)
  double last_save_s = -1.0;  ///< uptime at the last successful save (-1: never)
};

status::ServerStatus MakeServerStatus(const ServerBackend& backend, const ServerCommStats& comm,
                                      const std::vector<rt::TopicCountersSnapshot>& traffic, const DaemonInfo& info);

class StatusPublisher {
 public:
  /// A writer on `session` with the ccm_server_status_writer profile; nullptr + error if the
  /// QoS file lacks it.
  static std::unique_ptr<StatusPublisher> Create(rt::DdsSession& session, std::string* error);
  bool Publish(const status::ServerStatus& status) { return writer_->Write(status); }

 private:
  std::unique_ptr<rt::TypedWriter<status::ServerStatusPubSubType>> writer_;
};

}  // namespace ccm::server
