#include "server_runtime/server_comm.h"

#include <spdlog/spdlog.h>

#include "runtime_common/topics.h"

namespace ccm::server {

using Clock = std::chrono::steady_clock;

std::unique_ptr<ServerComm> ServerComm::Create(const ServerConfig& config, rt::SessionOptions session_options,
                                               std::string* error) {
  session_options.participant_name = "ccm_server";
  auto session = rt::DdsSession::Create(session_options, error);
  if (!session) return nullptr;
  std::unique_ptr<ServerComm> comm(new ServerComm(config, std::move(session)));
  rt::DdsSession& s = *comm->session_;
  // New data: block the listener when the server falls behind (back-pressure, no loss).
  comm->keyframe_reader_ = rt::TypedReader<msg::KeyframeFullPubSubType>::Create(
      s, rt::kTopicKeyframes, rt::kProfileNewDataReader, {256, rt::OverflowPolicy::kBlock}, error);
  if (!comm->keyframe_reader_) return nullptr;
  comm->status_reader_ = rt::TypedReader<msg::AgentStatusPubSubType>::Create(
      s, rt::kTopicAgentStatus, rt::kProfileStatusReader, {64, rt::OverflowPolicy::kDropOldest}, error);
  if (!comm->status_reader_) return nullptr;
  comm->server_writer_ = rt::TypedWriter<msg::ServerToAgentPubSubType>::Create(
      s, rt::kTopicServerToAgent, rt::kProfileServerWriter, error);
  if (!comm->server_writer_) return nullptr;
  return comm;
}

ServerComm::ServerComm(ServerConfig config, std::unique_ptr<rt::DdsSession> session)
    : config_(std::move(config)), session_(std::move(session)) {}

ServerComm::~ServerComm() { Stop(); }

void ServerComm::Start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { Run(); });
}

void ServerComm::Stop() {
  if (!running_.exchange(false)) return;
  thread_.join();
}

ServerStats ServerComm::Stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

void ServerComm::OnKeyframe(const msg::KeyframeFull& kf) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (kf.protocol_version() != msg::kProtocolVersion) {
    ++stats_.bad_version;
    return;
  }
  if (stats_.agents.size() >= static_cast<std::size_t>(config_.max_agents) && !stats_.agents.count(kf.agent_id())) {
    spdlog::warn("ignoring agent {}: max_agents = {} reached", kf.agent_id(), config_.max_agents);
    return;
  }
  AgentRecord& agent = stats_.agents[kf.agent_id()];
  if (!agent.keyframes.insert(kf.id()).second) ++agent.duplicates;
  // Ack duplicates too: the agent resent because it never saw our first ack.
  agent.pending_acks.emplace_back(kf.id(), config_.ack_repeats);
}

void ServerComm::PublishAcks() {
  std::vector<msg::ServerToAgent> out;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [agent_id, agent] : stats_.agents) {
      if (agent.pending_acks.empty()) continue;
      msg::ServerToAgent m;
      m.protocol_version(msg::kProtocolVersion);
      m.agent_id(agent_id);
      m.stamp_ns(std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count());
      m.ref_kf_id(agent.last_ref_kf);
      for (auto& [id, remaining] : agent.pending_acks) {
        if (m.acked_kf_ids().size() >= msg::kMaxAcks) break;
        m.acked_kf_ids().push_back(id);
        --remaining;
      }
      while (!agent.pending_acks.empty() && agent.pending_acks.front().second <= 0) agent.pending_acks.pop_front();
      out.push_back(std::move(m));
    }
  }
  for (const auto& m : out) {
    if (server_writer_->Write(m)) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.messages_sent;
    }
  }
}

void ServerComm::Run() {
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / config_.publish_rate_hz));
  auto next_publish = Clock::now() + period;
  while (running_) {
    if (auto kf = keyframe_reader_->Pop(std::chrono::milliseconds(20))) OnKeyframe(*kf);
    while (auto status = status_reader_->Pop(std::chrono::milliseconds(0))) {
      std::lock_guard<std::mutex> lock(mutex_);
      AgentRecord& agent = stats_.agents[status->agent_id()];
      ++agent.status_msgs;
      agent.last_ref_kf = status->ref_kf_id();
    }
    if (Clock::now() >= next_publish) {
      PublishAcks();
      next_publish += period;
    }
  }
}

}  // namespace ccm::server
