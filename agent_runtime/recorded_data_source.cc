#include "agent_runtime/recorded_data_source.h"

#include <algorithm>

namespace ccm::agent {
namespace {

template <typename IdT>
IdT Renamed(const std::map<AgentId, AgentId>& to, IdT id) {
  if (!id.valid()) return id;
  const auto it = to.find(id.agent());
  return it == to.end() ? id : IdT::Make(it->second, id.counter());
}

}  // namespace

void RemapAgents(const std::map<AgentId, AgentId>& to, AgentBatch* b) {
  const auto it = to.find(b->agent);
  if (it != to.end()) b->agent = it->second;
  b->segment = Renamed(to, b->segment);
  b->reference_kf = Renamed(to, b->reference_kf);
  for (KeyframeData& k : b->keyframes) {
    k.id = Renamed(to, k.id);
    k.segment = Renamed(to, k.segment);
    k.predecessor = Renamed(to, k.predecessor);
    k.parent = Renamed(to, k.parent);
    for (auto& link : k.point_links) link.second = Renamed(to, link.second);
  }
  for (MapPointData& p : b->map_points) {
    p.id = Renamed(to, p.id);
    p.segment = Renamed(to, p.segment);
    p.reference_kf = Renamed(to, p.reference_kf);
    for (auto& obs : p.observations) obs.first = Renamed(to, obs.first);
  }
  for (KeyframePoseUpdate& u : b->keyframe_updates) {
    u.id = Renamed(to, u.id);
    u.segment = Renamed(to, u.segment);
    u.predecessor = Renamed(to, u.predecessor);
    u.parent = Renamed(to, u.parent);
  }
  for (MapPointPositionUpdate& u : b->map_point_updates) {
    u.id = Renamed(to, u.id);
    u.reference_kf = Renamed(to, u.reference_kf);
  }
}

RecordedDataSource::RecordedDataSource(std::vector<AgentBatch> batches, int64_t t0_ns, Clock::time_point start,
                                       double speed)
    : batches_(std::move(batches)), t0_ns_(t0_ns), start_(start), speed_(speed > 0 ? speed : 1.0) {
  if (!batches_.empty()) duration_s_ = static_cast<double>(batches_.back().stamp_ns - batches_.front().stamp_ns) * 1e-9;
  for (const AgentBatch& b : batches_) keyframes_left_ += b.keyframes.size();
}

bool RecordedDataSource::Due(const AgentBatch& b, Clock::time_point now) const {
  const double recorded_s = static_cast<double>(b.stamp_ns - t0_ns_) * 1e-9;
  return std::chrono::duration<double>(now - start_).count() * speed_ >= recorded_s;
}

AgentBatch RecordedDataSource::TakeBatch(int64_t /*now_ns*/, bool /*flush*/) {
  const auto now = Clock::now();
  AgentBatch out;
  size_t next = next_.load();
  bool any = false;
  // Due batches of one segment go out together: an update's segment is the batch's.
  while (next < batches_.size() && Due(batches_[next], now) && (!any || batches_[next].segment == out.segment)) {
    AgentBatch& b = batches_[next++];
    if (!any) {
      out.agent = b.agent;
      out.segment = b.segment;
      any = true;
    }
    out.reference_kf = b.reference_kf;
    out.stamp_ns = b.stamp_ns;
    keyframes_left_ -= b.keyframes.size();
    for (KeyframeData& k : b.keyframes) {
      ++keyframes_taken_;
      if (k.anchor_only) ++anchors_taken_;
      sent_[k.id] = k;
      out.keyframes.push_back(std::move(k));
    }
    std::move(b.map_points.begin(), b.map_points.end(), std::back_inserter(out.map_points));
    std::move(b.keyframe_updates.begin(), b.keyframe_updates.end(), std::back_inserter(out.keyframe_updates));
    std::move(b.map_point_updates.begin(), b.map_point_updates.end(), std::back_inserter(out.map_point_updates));
    b = AgentBatch{};  // played: its memory is not needed any more
  }
  next_.store(next);
  if (!resend_.empty()) {
    std::vector<KeyframeData> again;
    for (const KeyframeId id : resend_) again.push_back(sent_.at(id));
    resend_.clear();
    if (!any && !again.empty()) {
      out.agent = again.front().id.agent();
      out.segment = again.back().segment;
      out.reference_kf = again.back().id;
    }
    out.keyframes.insert(out.keyframes.begin(), std::make_move_iterator(again.begin()),
                         std::make_move_iterator(again.end()));
  }
  return out;
}

bool RecordedDataSource::Resend(KeyframeId id) {
  if (sent_.count(id) == 0) return false;
  if (std::find(resend_.begin(), resend_.end(), id) == resend_.end()) resend_.push_back(id);
  return true;
}

void RecordedDataSource::ApplyServerData(ServerMapData data) {
  server_keyframes_ += data.keyframes.size();
  server_points_ += data.map_points.size();
}

AgentDataSource::Counters RecordedDataSource::counters() const {
  Counters c;
  c.keyframes_created = keyframes_taken_;
  c.anchors_sent = anchors_taken_;
  // Keyframes not played yet count as held back, so AgentComm::Drained() waits for them.
  c.deferred = keyframes_left_;
  return c;
}

}  // namespace ccm::agent
