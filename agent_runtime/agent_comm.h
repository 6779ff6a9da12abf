// The agent's communication module (CCM-SLAM section 4.4): publishes new keyframes
// (RELIABLE new-data profile) and status heartbeats, receives server messages, runs the
// optimistic ack/resend scheme and keeps every unacknowledged keyframe until the server
// has it. Owns one thread (started by Start(), joined by Stop()/destructor); Send() and
// Stats() may be called from any thread.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "agent_runtime/ack_tracker.h"
#include "agent_runtime/agent_config.h"
#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/typed_endpoints.h"

namespace ccm::agent {

struct AgentCommStats {
  std::uint64_t kfs_sent = 0;        // first transmissions
  std::uint64_t kfs_resent = 0;
  std::uint64_t kfs_acked = 0;
  std::uint64_t kfs_unacked = 0;
  std::uint64_t write_failures = 0;
  std::uint64_t server_msgs = 0;
  std::uint64_t kfs_lost = 0;         // dropped unacknowledged because the buffer was full
};

class AgentComm {
 public:
  static std::unique_ptr<AgentComm> Create(const AgentConfig& config, rt::SessionOptions session_options,
                                           std::string* error);
  ~AgentComm();

  void Start();
  void Stop();
  /// Queues a new keyframe for sending (blocks briefly if the comm thread is behind).
  bool Send(msg::KeyframeFull keyframe);
  AgentCommStats Stats() const;
  bool AllAcked() const;
  std::vector<rt::TopicCountersSnapshot> Traffic() const { return session_->TrafficSnapshot(); }
  int matched_servers() const { return keyframe_writer_->matched(); }

 private:
  AgentComm(AgentConfig config, std::unique_ptr<rt::DdsSession> session);
  void Run();
  void Transmit(const msg::KeyframeFull& kf, bool resend);
  void HandleServerMessage(const msg::ServerToAgent& message);
  void PublishStatus();

  AgentConfig config_;
  std::unique_ptr<rt::DdsSession> session_;  // destroyed last (declared first)
  std::unique_ptr<rt::TypedWriter<msg::KeyframeFullPubSubType>> keyframe_writer_;
  std::unique_ptr<rt::TypedWriter<msg::AgentStatusPubSubType>> status_writer_;
  std::unique_ptr<rt::TypedReader<msg::ServerToAgentPubSubType>> server_reader_;
  rt::BoundedQueue<msg::KeyframeFull> outbox_{64, rt::OverflowPolicy::kBlock};

  // Comm-thread state (only Run() touches these, Stats() reads under stats_mutex_).
  AckTracker acks_;
  std::map<KeyframeId, msg::KeyframeFull> unacked_;  // bounded by N + B
  KeyframeId newest_;
  mutable std::mutex stats_mutex_;
  AgentCommStats stats_;

  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace ccm::agent
