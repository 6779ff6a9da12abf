#include "server_runtime/server_comm.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>

#include "runtime_common/topics.h"
#include "runtime_common/wall_clock.h"

namespace ccm::server {
namespace {

using Clock = std::chrono::steady_clock;

// Caps per intake cycle, so one flooding agent cannot starve the outgoing side of the loop.
constexpr int kMaxKeyframesPerCycle = 64;
constexpr int kMaxOtherPerCycle = 8192;
constexpr int kMaxBatchesPerCycle = 16;

// Longest sleep of an idle comm thread: agents discovered without data get their writers,
// and liveliness is checked, at least this often.
constexpr std::chrono::milliseconds kMaxIdle(100);

// Agent ids are 16 bits on the wire; 0 is never a valid agent.
bool ValidAgentId(uint16_t id) { return id != 0; }

}  // namespace

std::unique_ptr<ServerComm> ServerComm::Create(const ServerConfig& config, rt::SessionOptions session_options,
                                               ServerBackend* backend, std::string* error) {
  session_options.participant_name = "ccm_server";
  session_options.track_agent_participants = true;  // agents' writers are made at discovery
  auto session = rt::DdsSession::Create(session_options, error);
  if (!session) return nullptr;
  std::unique_ptr<ServerComm> c(new ServerComm(config, std::move(session), backend));
  rt::DdsSession& s = *c->session_;
  using namespace rt;
  // Every agent writes in its own partition (agent_<id>); the server reads them all and
  // checks each message's agent id against its writer's partition (FromItsPartition). With
  // the secure profile, access control lets only agent <id>'s certificate write there.
  // New data: the listener waits only if the comm thread itself is stuck (it never waits on
  // SLAM work: Submit only queues), so nothing reliable is lost in the server process.
  c->keyframe_reader_ = TypedReader<msg::KeyframeFullPubSubType>::Create(
      s, kTopicKeyframes, kProfileNewDataReader, {256, OverflowPolicy::kBlock, &c->wakeup_}, error, kAllAgentsPartition);
  if (!c->keyframe_reader_) return nullptr;
  c->point_reader_ = TypedReader<msg::MapPointBatchPubSubType>::Create(
      s, kTopicMapPoints, kProfileNewDataReader, {1024, OverflowPolicy::kBlock, &c->wakeup_}, error, kAllAgentsPartition);
  if (!c->point_reader_) return nullptr;
  // Updates are superseded by newer ones: drop the oldest when behind.
  c->kf_update_reader_ = TypedReader<msg::KeyframeUpdatePubSubType>::Create(
      s, kTopicKeyframeUpdates, kProfileUpdateReader, {8192, OverflowPolicy::kDropOldest, &c->wakeup_}, error, kAllAgentsPartition);
  if (!c->kf_update_reader_) return nullptr;
  c->mp_update_reader_ = TypedReader<msg::MapPointUpdateBatchPubSubType>::Create(
      s, kTopicMapPointUpdates, kProfileUpdateReader, {256, OverflowPolicy::kDropOldest, &c->wakeup_}, error, kAllAgentsPartition);
  if (!c->mp_update_reader_) return nullptr;
  c->status_reader_ = TypedReader<msg::AgentStatusPubSubType>::Create(
      s, kTopicAgentStatus, kProfileStatusReader, {256, OverflowPolicy::kDropOldest, &c->wakeup_}, error, kAllAgentsPartition);
  if (!c->status_reader_) return nullptr;
  return c;
}

ServerComm::ServerComm(ServerConfig config, std::unique_ptr<rt::DdsSession> session, ServerBackend* backend)
    : config_(std::move(config)),
      session_(std::move(session)),
      backend_(backend),
      start_(Clock::now()),
      epoch_(static_cast<uint64_t>(std::max<int64_t>(1, rt::WallClockNs()))) {}

ServerComm::~ServerComm() { Stop(); }

void ServerComm::Start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { Run(); });
}

void ServerComm::Stop() {
  if (!running_.exchange(false)) return;
  wakeup_.Signal();
  thread_.join();
}

ServerCommStats ServerComm::Stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  ServerCommStats s = stats_;
  s.elapsed_s = Elapsed();
  return s;
}

double ServerComm::Elapsed() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

void ServerComm::Run() {
  while (running_) {
    const bool got = Intake();
    PublishToAgents();
    CheckLiveliness();
    if (!got) wakeup_.WaitFor(NextWake() - Clock::now());
  }
  PublishToAgents();  // the last acks
}

bool ServerComm::Admit(AgentId agent, const char* what) {
  std::vector<AgentId> released;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = stats_.agents.find(agent);
    if (it == stats_.agents.end()) {
      if (stats_.agents.size() >= static_cast<size_t>(config_.max_agents)) released = ReleaseIdleAgentsLocked();
      if (stats_.agents.size() >= static_cast<size_t>(config_.max_agents)) {
        ++stats_.refused_agents;
        if (refused_logged_.insert(agent).second) {
          spdlog::warn("refusing agent {} ({}): max_agents = {} reached", agent, what, config_.max_agents);
        }
        return false;
      }
      it = stats_.agents.emplace(agent, AgentLink{}).first;
      spdlog::info("agent {} joined", agent);
    }
    AgentLink& link = it->second;
    link.last_seen_s = Elapsed();
    if (!link.alive) {
      if (link.leaves > 0) spdlog::info("agent {} is back", agent);
      link.alive = true;
    }
  }
  // Outside the stats lock: deleting DDS writers calls into DDS.
  for (const AgentId a : released) {
    states_.erase(a);
    writers_.erase(a);
    reassembly_.Forget(a);
  }
  return true;
}

std::vector<AgentId> ServerComm::ReleaseIdleAgentsLocked() {
  std::vector<AgentId> out;
  if (config_.agent_slot_release_s <= 0.0) return out;
  const double now = Elapsed();
  for (auto it = stats_.agents.begin(); it != stats_.agents.end();) {
    const double silent = now - it->second.last_seen_s;
    if (!it->second.alive && silent >= config_.agent_slot_release_s) {
      spdlog::info("agent {}: slot released for a new agent after {:.0f} s of silence (its maps stay)", it->first,
                   silent);
      out.push_back(it->first);
      refused_logged_.erase(it->first);
      it = stats_.agents.erase(it);
      ++stats_.released_agents;
    } else {
      ++it;
    }
  }
  return out;
}

bool ServerComm::FromItsPartition(const eprosima::fastrtps::rtps::GUID_t& writer, AgentId agent, const char* what) {
  const std::optional<std::string> partition = session_->WriterPartition(writer);
  if (partition && rt::AgentIdOfPartition(*partition) == static_cast<int>(agent)) return true;
  // Not charged to `agent`: the sender is someone else (or not yet discovered, then the
  // agent resends what goes unacknowledged).
  const std::string where = partition ? "partition '" + *partition + "'" : "a writer not (yet) discovered";
  if (logged_kinds_.insert(partition ? "wrong partition" : "undiscovered writer").second) {
    spdlog::warn("ignored a {} claiming agent {} from {} (only agent {}'s partition may carry its data; further "
                 "ones are only counted)",
                 what, agent, where, agent);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.wrong_partition;
  return false;
}

void ServerComm::Reject(AgentId agent, const std::string& reason) {
  const std::string kind = conv::ReasonKind(reason);
  if (logged_kinds_.insert(kind).second) {
    spdlog::warn("rejected a message from agent {}: {} (further ones of this kind are only counted)", agent, reason);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.rejected;
  ++stats_.rejected_by_kind[kind];
  if (auto it = stats_.agents.find(agent); it != stats_.agents.end()) ++it->second.rejected;
}

Clock::time_point ServerComm::NextWake() const {
  Clock::time_point next = Clock::now() + kMaxIdle;
  for (const auto& [agent, st] : states_) next = std::min(next, st.next_publish);
  if (const auto held = reassembly_.NextDeadline()) next = std::min(next, *held);
  return next;
}

template <typename Reader, typename Handler>
bool ServerComm::Drain(Reader& reader, int max, const char* what, Handler&& handle) {
  bool any = false;
  for (int n = 0; n < max; ++n) {
    auto received = reader.PopWithWriter(std::chrono::milliseconds(0));
    if (!received) break;
    any = true;
    const AgentId agent = received->msg.agent_id();
    if (!ValidAgentId(agent) || !FromItsPartition(received->writer, agent, what)) continue;
    handle(agent, received->msg);
  }
  return any;
}

bool ServerComm::Intake() {
  BatchSet batches;
  // Heartbeats first: they admit agents and carry the reference keyframe.
  const bool got = Drain(*status_reader_, std::numeric_limits<int>::max(), "status",
                         [&](AgentId agent, const auto& m) { OnStatus(agent, m); });
  bool data = Drain(*keyframe_reader_, kMaxKeyframesPerCycle, "keyframe",
                    [&](AgentId agent, const auto& m) { OnKeyframe(agent, m); });
  data |= Drain(*point_reader_, kMaxBatchesPerCycle, "map points",
                [&](AgentId agent, const auto& m) { OnPoints(agent, m, &batches); });
  data |= Drain(*kf_update_reader_, kMaxOtherPerCycle, "keyframe update",
                [&](AgentId agent, const auto& m) { OnKeyframeUpdate(agent, m, &batches); });
  data |= Drain(*mp_update_reader_, kMaxBatchesPerCycle, "map point updates",
                [&](AgentId agent, const auto& m) { OnPointUpdates(agent, m, &batches); });
  if (data) {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.last_data_s = Elapsed();
  }
  const auto incomplete = reassembly_.Release(Clock::now(), &batches);
  if (!incomplete.empty()) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [agent, n] : incomplete) stats_.agents[agent].keyframes_released_incomplete += n;
  }
  SubmitBatches(&batches);
  return got || data;
}

void NoteSegment(MapId segment, AgentLink* link) {
  if (link->segments.size() < kMaxSegmentsListed || link->segments.count(segment)) {
    link->segments.insert(segment);
  } else {
    ++link->segments_not_listed;
  }
}

void ApplyStatus(const conv::AgentStatusData& st, AgentLink* link) {
  ++link->status_msgs;
  if (st.reference_kf.valid()) link->reference_kf = st.reference_kf;
  if (st.segment.valid()) {
    link->segment = st.segment;
    NoteSegment(st.segment, link);
  }
  link->kfs_created = st.kfs_created;
  link->kfs_sent = st.kfs_sent;
  link->kfs_acked = st.kfs_acked;
  link->kfs_resent = st.kfs_resent;
  link->kfs_lost = st.kfs_lost;
  link->tracking_state = st.tracking_state;
}

void ServerComm::OnStatus(AgentId agent, const msg::AgentStatus& m) {
  std::string error;
  const auto st = conv::FromMsg(m, &error);
  if (!st) {
    Reject(agent, error);
    return;
  }
  if (!Admit(agent, "status")) return;
  states_[agent].deltas.OnHoldings(st->holdings);
  std::lock_guard<std::mutex> lock(mutex_);
  ApplyStatus(*st, &stats_.agents[agent]);
}

void ServerComm::OnKeyframe(AgentId agent, const msg::KeyframeFull& m) {
  if (!Admit(agent, "keyframe")) return;
  std::string error;
  KeyframeId ref;
  auto d = conv::FromMsg(m, &cameras_, &error, &ref);
  if (!d) {
    Reject(agent, error);
    return;
  }
  const MapId segment = d->segment;
  reassembly_.AddKeyframe(agent, std::move(*d), ref, Clock::now());
  std::lock_guard<std::mutex> lock(mutex_);
  AgentLink& link = stats_.agents[agent];
  ++link.keyframes;
  NoteSegment(segment, &link);
}

void ServerComm::OnPoints(AgentId agent, const msg::MapPointBatch& m, BatchSet* batches) {
  if (!Admit(agent, "map points")) return;
  std::string error;
  const auto segment = conv::BatchSegment(m, &error);
  if (!segment) {
    Reject(agent, error);
    return;
  }
  int64_t accepted = 0;
  for (const msg::MapPointFull& p : m.points()) {
    auto d = conv::FromMsg(p, agent, *segment, &error);
    if (!d) {
      Reject(agent, error);
      continue;
    }
    reassembly_.AddMapPoint(agent, std::move(*d), Clock::now(), batches);
    ++accepted;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  stats_.agents[agent].map_points += accepted;
}

void ServerComm::OnKeyframeUpdate(AgentId agent, const msg::KeyframeUpdate& m, BatchSet* batches) {
  if (!Admit(agent, "keyframe update")) return;
  std::string error;
  auto d = conv::FromMsg(m, &error);
  if (!d) {
    Reject(agent, error);
    return;
  }
  if (reassembly_.AddKeyframeUpdate(agent, *d, batches) != KeyframeReassembly::UpdateFate::kBatched) return;
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.agents[agent].keyframe_updates;
}

void ServerComm::OnPointUpdates(AgentId agent, const msg::MapPointUpdateBatch& m, BatchSet* batches) {
  if (!Admit(agent, "map point updates")) return;
  std::string error;
  const auto segment = conv::BatchSegment(m, &error);
  if (!segment) {
    Reject(agent, error);
    return;
  }
  int64_t accepted = 0;
  for (const msg::MapPointUpdate& u : m.updates()) {
    auto d = conv::FromMsg(u, agent, &error);
    if (!d) {
      Reject(agent, error);
      continue;
    }
    if (reassembly_.AddMapPointUpdate(agent, *d, *segment, batches) == KeyframeReassembly::UpdateFate::kBatched) {
      ++accepted;
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  stats_.agents[agent].map_point_updates += accepted;
}

void ServerComm::SubmitBatches(BatchSet* batches) {
  for (AgentBatch& batch : batches->Take()) {
    const AgentId agent = batch.agent;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      AgentLink& link = stats_.agents[agent];
      // The server answers relative to the newest reference keyframe the agent named.
      if (!batch.reference_kf.valid()) batch.reference_kf = link.reference_kf;
      if (batch.reference_kf.valid() && (!link.reference_kf.valid() || link.reference_kf < batch.reference_kf)) {
        link.reference_kf = batch.reference_kf;
      }
    }
    batch.stamp_ns = rt::WallClockNs();
    const int result = backend_->Submit(std::move(batch));
    std::lock_guard<std::mutex> lock(mutex_);
    AgentLink& link = stats_.agents[agent];
    if (result < 0) {
      ++link.batches_dropped;
    } else {
      ++link.batches_submitted;
    }
  }
}

void ServerComm::CheckLiveliness() {
  const double now = Elapsed();
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& [id, link] : stats_.agents) {
    if (link.alive && now - link.last_seen_s > config_.liveliness_timeout_s) {
      link.alive = false;
      ++link.leaves;
      spdlog::warn("agent {} left: nothing heard for {:.1f} s (its maps stay on the server)", id, now - link.last_seen_s);
    }
  }
}

}  // namespace ccm::server
