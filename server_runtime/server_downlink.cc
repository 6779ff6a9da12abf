// ServerComm's outgoing side (server -> agent): the acks and the neighbourhoods, each on
// its own writer per agent (server_comm.h explains why). Comm thread only.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "runtime_common/topics.h"
#include "runtime_common/wall_clock.h"
#include "server_runtime/server_comm.h"

namespace ccm::server {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

void ServerComm::PublishToAgents() {
  const auto now = Clock::now();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / config_.publish_rate_hz));
  std::vector<std::pair<AgentId, KeyframeId>> agents;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [id, link] : stats_.agents) agents.emplace_back(id, link.reference_kf);
  }
  // Writers for agents seen in participant discovery, before their first data (bounded by
  // max_agents: a name grants nothing, so strangers cannot make the server create writers).
  for (const int id : session_->TakeDiscoveredAgents()) {
    if (writers_.count(static_cast<AgentId>(id)) || writers_.size() >= static_cast<size_t>(config_.max_agents)) continue;
    EnsureWriters(static_cast<AgentId>(id));
  }
  for (const auto& [agent, reference_kf] : agents) {
    if (!EnsureWriters(agent)) continue;
    AgentState& st = states_[agent];
    AgentWriters& writers = writers_[agent];
    if (now < st.next_publish) continue;
    st.next_publish = now + period;
    const AgentAcks fresh = backend_->TakeAcks(agent);
    for (const KeyframeId id : fresh.keyframes) st.kf_acks.push_back({id.packed(), config_.ack_repeats});
    // Point acks are off by default: ccm_agent does not use them (a point is resent with
    // its keyframe), and at ~300 points per second they made every ack message ~6 kB, i.e.
    // 5 fragments that a lossy link must all deliver (one datagram without them).
    if (config_.ack_points) {
      for (const MapPointId id : fresh.map_points) st.mp_acks.push_back({id.packed(), config_.ack_repeats});
    }
    // Oldest first; whatever does not fit in one message goes in the next.
    auto take = [](std::deque<PendingAck>* pending, auto make_id) {
      using IdT = decltype(make_id(0));
      std::vector<IdT> ids;
      for (PendingAck& a : *pending) {
        if (ids.size() >= msg::kMaxAcks) break;
        ids.push_back(make_id(a.id));
        --a.repeats_left;
      }
      pending->erase(std::remove_if(pending->begin(), pending->end(), [](const PendingAck& a) { return a.repeats_left <= 0; }),
                     pending->end());
      return ids;
    };
    const auto kf_ids = take(&st.kf_acks, [](uint64_t v) { return KeyframeId(v); });
    const auto mp_ids = take(&st.mp_acks, [](uint64_t v) { return MapPointId(v); });
    int sent = 0, shared = 0, deferred = 0, kfs_full = 0, kfs_as_poses = 0, points_full = 0, points_as_positions = 0;
    const bool with_acks = !kf_ids.empty() || !mp_ids.empty();
    const bool new_save = persists() && st.persisted_sent != persisted_seq_.load();
    if (with_acks || new_save || now - st.last_ack_message >= kAckHeartbeat) {
      const conv::ServerAckStamp stamp = NextAckStamp(with_acks);
      sent += writers.acks->Write(conv::ToMsg(agent, rt::WallClockNs(), kf_ids, mp_ids, nullptr, stamp)) ? 1 : 0;
      st.last_ack_message = now;
      st.persisted_sent = stamp.persisted_seq;
    }
    if (config_.map_sharing && config_.neighbourhood_k > 0 && reference_kf.valid() && reference_kf != st.shared_ref) {
      // Zero timeout: only asks whether the agent's reader has the last one.
      const bool delivered = writers.neighbourhoods->WaitForAcknowledgments(std::chrono::milliseconds(0));
      if (!delivered && now - st.last_neighbourhood < kNeighbourhoodPatience) {
        deferred = 1;
      } else if (const std::unordered_set<KeyframeId> held = st.deltas.HeldKeyframes();
                 auto data = backend_->Neighbourhood(agent, reference_kf, &held)) {
        st.shared_ref = reference_kf;
        st.last_neighbourhood = now;
        const int64_t stamp = rt::WallClockNs();
        st.deltas.MarkHeldPoints(&*data);
        if (writers.neighbourhoods->Write(conv::ToMsg(agent, stamp, {}, {}, &*data, NextAckStamp(false)))) {
          ++sent, ++shared;
          st.deltas.RecordSent(stamp, *data);
          for (const ServerKeyframe& kf : data->keyframes) ++(kf.held ? kfs_as_poses : kfs_full);
          for (const ServerMapPoint& mp : data->map_points) ++(mp.held ? points_as_positions : points_full);
        }
      }
    }
    std::lock_guard<std::mutex> lock(mutex_);
    AgentLink& link = stats_.agents[agent];
    link.messages_sent += sent;
    link.neighbourhoods_sent += shared;
    link.neighbourhoods_deferred += deferred;
    link.neighbourhood_keyframes_full += kfs_full;
    link.neighbourhood_keyframes_as_poses += kfs_as_poses;
    link.neighbourhood_points_full += points_full;
    link.neighbourhood_points_as_positions += points_as_positions;
  }
}

conv::ServerAckStamp ServerComm::NextAckStamp(bool with_acks) {
  conv::ServerAckStamp stamp;
  stamp.epoch = epoch_;
  // Numbered after the acks were taken (TakeAcks): a snapshot that starts after reading
  // AckSeqIssued() holds every keyframe acked in messages up to it.
  if (with_acks) stamp.ack_seq = ++ack_seq_issued_;
  stamp.persisted_seq = persists() ? persisted_seq_.load() : ack_seq_issued_.load();
  return stamp;
}

void ServerComm::OnPersisted(uint64_t seq) {
  uint64_t old = persisted_seq_.load();
  while (seq > old && !persisted_seq_.compare_exchange_weak(old, seq)) {
  }
}

bool ServerComm::EnsureWriters(AgentId agent) {
  AgentWriters& w = writers_[agent];
  if (w.acks && w.neighbourhoods) return true;
  using Writer = rt::TypedWriter<msg::ServerToAgentPubSubType>;
  const std::string partition = rt::AgentPartition(agent);
  std::string error;
  if (!w.neighbourhoods) {
    w.neighbourhoods = Writer::Create(*session_, rt::kTopicServerToAgent, rt::kProfileServerWriter, &error, partition);
    if (!w.neighbourhoods) {
      spdlog::error("agent {}: no writer for its server messages: {}", agent, error);
      return false;
    }
  }
  w.acks = Writer::Create(*session_, rt::kTopicServerToAgent, rt::kProfileServerAckWriter, &error, partition);
  if (!w.acks) {
    // A QoS file from before the ack profile existed: acks share the neighbourhoods' QoS.
    spdlog::warn("agent {}: {}; acks use profile '{}'", agent, error, rt::kProfileServerWriter);
    w.acks = Writer::Create(*session_, rt::kTopicServerToAgent, rt::kProfileServerWriter, &error, partition);
    if (!w.acks) {
      spdlog::error("agent {}: no writer for its acks: {}", agent, error);
      return false;
    }
  }
  return true;
}

}  // namespace ccm::server
