#include "agent_runtime/agent_comm.h"

#include <spdlog/spdlog.h>

#include "runtime_common/topics.h"

namespace ccm::agent {

using Clock = std::chrono::steady_clock;

std::unique_ptr<AgentComm> AgentComm::Create(const AgentConfig& config, rt::SessionOptions session_options,
                                             std::string* error) {
  session_options.participant_name = "ccm_agent_" + std::to_string(config.agent_id);
  auto session = rt::DdsSession::Create(session_options, error);
  if (!session) return nullptr;
  std::unique_ptr<AgentComm> comm(new AgentComm(config, std::move(session)));
  rt::DdsSession& s = *comm->session_;
  comm->keyframe_writer_ = rt::TypedWriter<msg::KeyframeFullPubSubType>::Create(
      s, rt::kTopicKeyframes, rt::kProfileNewDataWriter, error);
  if (!comm->keyframe_writer_) return nullptr;
  comm->status_writer_ = rt::TypedWriter<msg::AgentStatusPubSubType>::Create(
      s, rt::kTopicAgentStatus, rt::kProfileStatusWriter, error);
  if (!comm->status_writer_) return nullptr;
  comm->server_reader_ = rt::TypedReader<msg::ServerToAgentPubSubType>::Create(
      s, rt::kTopicServerToAgent, rt::kProfileServerReader, {16, rt::OverflowPolicy::kDropOldest}, error);
  if (!comm->server_reader_) return nullptr;
  return comm;
}

AgentComm::AgentComm(AgentConfig config, std::unique_ptr<rt::DdsSession> session)
    : config_(std::move(config)),
      session_(std::move(session)),
      acks_(std::chrono::milliseconds(static_cast<int>(config_.resend_holdoff_s * 1000))) {}

AgentComm::~AgentComm() { Stop(); }

void AgentComm::Start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { Run(); });
}

void AgentComm::Stop() {
  if (!running_.exchange(false)) return;
  outbox_.Close();
  thread_.join();
}

bool AgentComm::Send(msg::KeyframeFull keyframe) { return outbox_.Push(std::move(keyframe)); }

AgentCommStats AgentComm::Stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

bool AgentComm::AllAcked() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_.kfs_unacked == 0;
}

void AgentComm::Transmit(const msg::KeyframeFull& kf, bool resend) {
  const bool ok = keyframe_writer_->Write(kf);
  acks_.OnSent(KeyframeId(kf.id()), Clock::now());
  std::lock_guard<std::mutex> lock(stats_mutex_);
  if (!ok) ++stats_.write_failures;
  (resend ? stats_.kfs_resent : stats_.kfs_sent)++;
}

void AgentComm::HandleServerMessage(const msg::ServerToAgent& message) {
  if (message.protocol_version() != msg::kProtocolVersion || message.agent_id() != config_.agent_id) return;
  std::vector<KeyframeId> acked;
  for (auto id : message.acked_kf_ids()) acked.emplace_back(id);
  for (KeyframeId id : acks_.OnAcked(acked, Clock::now())) {
    if (auto it = unacked_.find(id); it != unacked_.end()) Transmit(it->second, true);
  }
  for (KeyframeId id : acked) unacked_.erase(id);
  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++stats_.server_msgs;
}

void AgentComm::PublishStatus() {
  msg::AgentStatus status;
  status.protocol_version(msg::kProtocolVersion);
  status.agent_id(static_cast<std::uint16_t>(config_.agent_id));
  status.stamp_ns(std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count());
  status.ref_kf_id(newest_.packed());
  const AgentCommStats s = Stats();
  status.kfs_sent(static_cast<std::uint32_t>(s.kfs_sent));
  status.kfs_acked(static_cast<std::uint32_t>(s.kfs_acked));
  status.kfs_resent(static_cast<std::uint32_t>(s.kfs_resent));
  status.kfs_lost(static_cast<std::uint32_t>(s.kfs_lost));
  status.write_failures(static_cast<std::uint32_t>(s.write_failures));
  status.tracking_state(1);
  status_writer_->Write(status);
}

void AgentComm::Run() {
  const auto status_period = std::chrono::duration<double>(1.0 / config_.status_rate_hz);
  const auto ack_timeout = std::chrono::milliseconds(static_cast<int>(config_.ack_timeout_s * 1000));
  const std::size_t capacity = static_cast<std::size_t>(config_.max_keyframes + config_.buffer_keyframes);
  auto next_status = Clock::now();
  while (running_) {
    if (auto kf = outbox_.Pop(std::chrono::milliseconds(20))) {
      newest_ = KeyframeId(kf->id());
      Transmit(*kf, false);
      unacked_[newest_] = std::move(*kf);
      while (unacked_.size() > capacity) {  // CCM-SLAM: over N + B, the oldest is dropped (counted)
        acks_.Forget(unacked_.begin()->first);
        unacked_.erase(unacked_.begin());
        std::lock_guard<std::mutex> lock(stats_mutex_);
        ++stats_.kfs_lost;
      }
    }
    while (auto message = server_reader_->Pop(std::chrono::milliseconds(0))) HandleServerMessage(*message);
    for (KeyframeId id : acks_.Overdue(ack_timeout, Clock::now())) {
      if (auto it = unacked_.find(id); it != unacked_.end()) Transmit(it->second, true);
    }
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      stats_.kfs_acked = acks_.acked_count();
      stats_.kfs_unacked = unacked_.size();
    }
    if (Clock::now() >= next_status) {
      PublishStatus();
      next_status += std::chrono::duration_cast<Clock::duration>(status_period);
    }
  }
}

}  // namespace ccm::agent
