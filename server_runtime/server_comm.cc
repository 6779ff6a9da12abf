#include "server_runtime/server_comm.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "runtime_common/topics.h"
#include "runtime_common/wall_clock.h"

namespace ccm::server {
namespace {

using Clock = std::chrono::steady_clock;

// Caps per intake cycle, so one flooding agent cannot starve the outgoing side of the loop.
constexpr int kMaxKeyframesPerCycle = 64;
constexpr int kMaxOtherPerCycle = 8192;
constexpr int kMaxBatchesPerCycle = 16;

constexpr std::chrono::milliseconds kMaxKeyframeHold(1500);
constexpr std::chrono::seconds kSeenWindow(120);
constexpr size_t kMaxEarlyUpdates = 65536;  // per agent and kind; beyond: the oldest go

// A pose update that reached the server before (or while holding) its full keyframe.
void ApplyPoseUpdate(const KeyframePoseUpdate& u, KeyframeData* kf) {
  kf->predecessor = u.predecessor;
  kf->pred_from_cam = u.pred_from_cam;
  kf->parent = u.parent;
  kf->parent_from_cam = u.parent_from_cam;
}

std::string VersionMismatch(const char* what, uint16_t version) {
  return std::string(what) + ": protocol version " + std::to_string(version) + ", expected " +
         std::to_string(msg::kProtocolVersion);
}

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
      s, kTopicKeyframes, kProfileNewDataReader, {256, OverflowPolicy::kBlock}, error, kAllAgentsPartition);
  if (!c->keyframe_reader_) return nullptr;
  c->point_reader_ = TypedReader<msg::MapPointBatchPubSubType>::Create(
      s, kTopicMapPoints, kProfileNewDataReader, {1024, OverflowPolicy::kBlock}, error, kAllAgentsPartition);
  if (!c->point_reader_) return nullptr;
  // Updates are superseded by newer ones: drop the oldest when behind.
  c->kf_update_reader_ = TypedReader<msg::KeyframeUpdatePubSubType>::Create(
      s, kTopicKeyframeUpdates, kProfileUpdateReader, {8192, OverflowPolicy::kDropOldest}, error, kAllAgentsPartition);
  if (!c->kf_update_reader_) return nullptr;
  c->mp_update_reader_ = TypedReader<msg::MapPointUpdateBatchPubSubType>::Create(
      s, kTopicMapPointUpdates, kProfileUpdateReader, {256, OverflowPolicy::kDropOldest}, error, kAllAgentsPartition);
  if (!c->mp_update_reader_) return nullptr;
  c->status_reader_ = TypedReader<msg::AgentStatusPubSubType>::Create(
      s, kTopicAgentStatus, kProfileStatusReader, {256, OverflowPolicy::kDropOldest}, error, kAllAgentsPartition);
  if (!c->status_reader_) return nullptr;
  return c;
}

ServerComm::ServerComm(ServerConfig config, std::unique_ptr<rt::DdsSession> session, ServerBackend* backend)
    : config_(std::move(config)), session_(std::move(session)), backend_(backend), start_(Clock::now()) {}

ServerComm::~ServerComm() { Stop(); }

void ServerComm::Start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { Run(); });
}

void ServerComm::Stop() {
  if (!running_.exchange(false)) return;
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
    // Idle: a short nap keeps the latency of a keyframe far below the agents' publish
    // period at no measurable CPU cost (the queues have no combined wait).
    if (!got) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  PublishToAgents();  // the last acks
}

bool ServerComm::Admit(AgentId agent, const char* what) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = stats_.agents.find(agent);
  if (it == stats_.agents.end()) {
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
  return true;
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

AgentBatch& ServerComm::BatchFor(std::map<BatchKey, AgentBatch>* batches, AgentId agent, MapId segment) {
  AgentBatch& b = (*batches)[{agent, segment.packed()}];
  b.agent = agent;
  b.segment = segment;
  return b;
}

bool ServerComm::Intake() {
  std::map<BatchKey, AgentBatch> batches;
  std::string error;
  bool got = false;
  // Heartbeats first: they admit agents and carry the reference keyframe.
  while (auto received = status_reader_->PopWithWriter(std::chrono::milliseconds(0))) {
    got = true;
    const msg::AgentStatus* st = &received->msg;
    const AgentId agent = st->agent_id();
    if (!ValidAgentId(agent) || !FromItsPartition(received->writer, agent, "status")) continue;
    if (st->protocol_version() != msg::kProtocolVersion) {
      Reject(agent, VersionMismatch("status", st->protocol_version()));
      continue;
    }
    const KeyframeId ref(st->ref_kf_id());
    const MapId segment(st->map_segment_id());
    if ((ref.valid() && ref.agent() != agent) || (segment.valid() && segment.agent() != agent)) {
      Reject(agent, "status: reference keyframe or segment of another agent");
      continue;
    }
    if (!Admit(agent, "status")) continue;
    std::lock_guard<std::mutex> lock(mutex_);
    AgentLink& link = stats_.agents[agent];
    ++link.status_msgs;
    if (ref.valid()) link.reference_kf = ref;
    if (segment.valid()) {
      link.segment = segment;
      link.segments.insert(segment);
    }
    link.kfs_created = st->kfs_created();
    link.kfs_sent = st->kfs_sent();
    link.kfs_acked = st->kfs_acked();
    link.kfs_resent = st->kfs_resent();
    link.kfs_lost = st->kfs_lost();
    link.tracking_state = st->tracking_state();
  }
  bool data = false;
  for (int n = 0; n < kMaxKeyframesPerCycle; ++n) {
    auto received = keyframe_reader_->PopWithWriter(std::chrono::milliseconds(0));
    if (!received) break;
    data = true;
    auto* m = &received->msg;
    const AgentId agent = m->agent_id();
    if (!ValidAgentId(agent) || !FromItsPartition(received->writer, agent, "keyframe") ||
        !Admit(agent, "keyframe")) {
      continue;
    }
    KeyframeId ref;
    auto d = conv::FromMsg(*m, &cameras_, &error, &ref);
    if (!d) {
      Reject(agent, error);
      continue;
    }
    seen_keyframes_[agent].Note(d->id.packed(), Clock::now());
    auto& early = early_[agent].keyframes;
    if (auto it = early.find(d->id.packed()); it != early.end()) {
      ApplyPoseUpdate(it->second, &*d);
      early.erase(it);
    }
    const MapId segment = d->segment;
    held_[agent].push_back({std::move(*d), ref, Clock::now()});
    std::lock_guard<std::mutex> lock(mutex_);
    AgentLink& link = stats_.agents[agent];
    ++link.keyframes;
    link.segments.insert(segment);
  }
  for (int n = 0; n < kMaxBatchesPerCycle; ++n) {
    auto received = point_reader_->PopWithWriter(std::chrono::milliseconds(0));
    if (!received) break;
    data = true;
    auto* m = &received->msg;
    const AgentId agent = m->agent_id();
    if (!ValidAgentId(agent) || !FromItsPartition(received->writer, agent, "map points") ||
        !Admit(agent, "map points")) {
      continue;
    }
    if (m->protocol_version() != msg::kProtocolVersion) {
      Reject(agent, VersionMismatch("map point batch", m->protocol_version()));
      continue;
    }
    int64_t accepted = 0;
    for (const msg::MapPointFull& p : m->points()) {
      auto d = p.agent_id() == agent ? conv::FromMsg(p, &error) : std::nullopt;
      if (!d) {
        Reject(agent, p.agent_id() == agent ? error : "map point: agent id differs from its batch's");
        continue;
      }
      seen_points_[agent].Note(d->id.packed(), Clock::now());
      auto& early = early_[agent].points;
      if (auto it = early.find(d->id.packed()); it != early.end()) {
        d->reference_kf = it->second.reference_kf;
        d->position_ref = it->second.position_ref;
        early.erase(it);
      }
      BatchFor(&batches, agent, d->segment).map_points.push_back(std::move(*d));
      ++accepted;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.agents[agent].map_points += accepted;
  }
  for (int n = 0; n < kMaxOtherPerCycle; ++n) {
    auto received = kf_update_reader_->PopWithWriter(std::chrono::milliseconds(0));
    if (!received) break;
    data = true;
    auto* m = &received->msg;
    const AgentId agent = m->agent_id();
    if (!ValidAgentId(agent) || !FromItsPartition(received->writer, agent, "keyframe update") ||
        !Admit(agent, "keyframe update")) {
      continue;
    }
    auto d = conv::FromMsg(*m, &error);
    if (!d) {
      Reject(agent, error);
      continue;
    }
    if (!seen_keyframes_[agent].Seen(d->id.packed(), d->id.counter())) {
      auto& early = early_[agent].keyframes;
      if (early.size() >= kMaxEarlyUpdates) early.clear();  // a flood of unknown ids: not worth keeping
      early[d->id.packed()] = *d;
      continue;
    }
    if (ApplyToHeld(agent, *d)) continue;
    BatchFor(&batches, agent, d->segment).keyframe_updates.push_back(*d);
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.agents[agent].keyframe_updates;
  }
  for (int n = 0; n < kMaxBatchesPerCycle; ++n) {
    auto received = mp_update_reader_->PopWithWriter(std::chrono::milliseconds(0));
    if (!received) break;
    data = true;
    auto* m = &received->msg;
    const AgentId agent = m->agent_id();
    if (!ValidAgentId(agent) || !FromItsPartition(received->writer, agent, "map point updates") ||
        !Admit(agent, "map point updates")) {
      continue;
    }
    if (m->protocol_version() != msg::kProtocolVersion) {
      Reject(agent, VersionMismatch("map point update batch", m->protocol_version()));
      continue;
    }
    int64_t accepted = 0;
    for (const msg::MapPointUpdate& u : m->updates()) {
      MapId segment;
      auto d = u.agent_id() == agent ? conv::FromMsg(u, &error, &segment) : std::nullopt;
      if (!d) {
        Reject(agent, u.agent_id() == agent ? error : "map point update: agent id differs from its batch's");
        continue;
      }
      if (!seen_points_[agent].Seen(d->id.packed(), d->id.counter())) {
        auto& early = early_[agent].points;
        if (early.size() >= kMaxEarlyUpdates) early.clear();
        early[d->id.packed()] = *d;
        continue;
      }
      BatchFor(&batches, agent, segment).map_point_updates.push_back(*d);
      ++accepted;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.agents[agent].map_point_updates += accepted;
  }
  if (data) {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.last_data_s = Elapsed();
  }
  ReleaseKeyframes(&batches);
  SubmitBatches(&batches);
  return got || data;
}

void ServerComm::SeenIds::Note(uint64_t packed, Clock::time_point now) {
  if (ids.insert(packed).second) order.emplace_back(now, packed);
  while (!order.empty() && now - order.front().first > kSeenWindow) {
    pruned_below = std::max(pruned_below, MapPointId(order.front().second).counter() + 1);  // same layout for every id kind
    ids.erase(order.front().second);
    order.pop_front();
  }
}

bool ServerComm::ApplyToHeld(AgentId agent, const KeyframePoseUpdate& u) {
  for (HeldKeyframe& h : held_[agent]) {
    if (h.data.id != u.id) continue;
    ApplyPoseUpdate(u, &h.data);
    return true;
  }
  return false;
}

void ServerComm::ReleaseKeyframes(std::map<BatchKey, AgentBatch>* batches) {
  const auto now = Clock::now();
  for (auto& [agent, held] : held_) {
    const SeenIds& seen = seen_points_[agent];
    while (!held.empty()) {
      const HeldKeyframe& h = held.front();
      const bool complete = std::all_of(h.data.point_links.begin(), h.data.point_links.end(), [&](const auto& link) {
        const MapPointId mp = link.second;
        return mp.agent() != agent || seen.Seen(mp.packed(), mp.counter());
      });
      if (!complete && now - h.since < kMaxKeyframeHold) break;  // keep the agent's order
      if (!complete) {
        std::lock_guard<std::mutex> lock(mutex_);
        ++stats_.agents[agent].keyframes_released_incomplete;
      }
      AgentBatch& b = BatchFor(batches, agent, h.data.segment);
      if (h.reference_kf.valid()) b.reference_kf = h.reference_kf;
      b.keyframes.push_back(std::move(held.front().data));
      held.pop_front();
    }
  }
}

void ServerComm::SubmitBatches(std::map<BatchKey, AgentBatch>* batches) {
  for (auto& [key, batch] : *batches) {
    const AgentId agent = key.first;
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
  batches->clear();
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
