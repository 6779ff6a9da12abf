// The server's communication module: receives keyframes and status from all agents,
// keeps one handler record per agent, and periodically sends each agent a ServerToAgent
// message acknowledging what was processed (each ack repeated `ack_repeats` times since
// the message is BEST_EFFORT). Owns one thread (Start/Stop); Stats() from any thread.
#pragma once

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/typed_endpoints.h"
#include "server_runtime/server_config.h"

namespace ccm::server {

struct AgentRecord {
  std::set<std::uint64_t> keyframes;       // unique KF ids received
  std::uint64_t duplicates = 0;            // resends of KFs we already had
  std::uint64_t status_msgs = 0;
  std::uint64_t last_ref_kf = 0;
  std::deque<std::pair<std::uint64_t, int>> pending_acks;  // (kf id, times still to send)
};

struct ServerStats {
  std::map<std::uint16_t, AgentRecord> agents;
  std::uint64_t messages_sent = 0;
  std::uint64_t bad_version = 0;
};

class ServerComm {
 public:
  static std::unique_ptr<ServerComm> Create(const ServerConfig& config, rt::SessionOptions session_options,
                                            std::string* error);
  ~ServerComm();
  void Start();
  void Stop();
  ServerStats Stats() const;
  std::vector<rt::TopicCountersSnapshot> Traffic() const { return session_->TrafficSnapshot(); }

 private:
  ServerComm(ServerConfig config, std::unique_ptr<rt::DdsSession> session);
  void Run();
  void OnKeyframe(const msg::KeyframeFull& kf);
  void PublishAcks();

  ServerConfig config_;
  std::unique_ptr<rt::DdsSession> session_;
  std::unique_ptr<rt::TypedReader<msg::KeyframeFullPubSubType>> keyframe_reader_;
  std::unique_ptr<rt::TypedReader<msg::AgentStatusPubSubType>> status_reader_;
  std::unique_ptr<rt::TypedWriter<msg::ServerToAgentPubSubType>> server_writer_;
  mutable std::mutex mutex_;  // guards stats_
  ServerStats stats_;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace ccm::server
