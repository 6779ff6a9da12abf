#include "server_runtime/keyframe_reassembly.h"

#include <algorithm>

namespace ccm::server {
namespace {

void ApplyPoseUpdate(const KeyframePoseUpdate& u, KeyframeData* kf) {
  kf->predecessor = u.predecessor;
  kf->pred_from_cam = u.pred_from_cam;
  kf->parent = u.parent;
  kf->parent_from_cam = u.parent_from_cam;
}

template <typename Map, typename Update>
void KeepEarly(Map* early, uint64_t id, const Update& u, size_t limit) {
  if (early->size() >= limit) early->clear();  // a flood of unknown ids: not worth keeping
  (*early)[id] = u;
}

}  // namespace

AgentBatch& BatchSet::For(AgentId agent, MapId segment) {
  AgentBatch& b = batches_[{agent, segment.packed()}];
  b.agent = agent;
  b.segment = segment;
  return b;
}

std::vector<AgentBatch> BatchSet::Take() {
  std::vector<AgentBatch> out;
  out.reserve(batches_.size());
  for (auto& [key, batch] : batches_) out.push_back(std::move(batch));
  batches_.clear();
  return out;
}

void KeyframeReassembly::SeenIds::Note(uint64_t packed, Clock::time_point now, std::chrono::seconds window) {
  if (ids.insert(packed).second) order.emplace_back(now, packed);
  while (!order.empty() && now - order.front().first > window) {
    // Keyframe and point ids share one layout (agent, counter).
    pruned_below = std::max(pruned_below, MapPointId(order.front().second).counter() + 1);
    ids.erase(order.front().second);
    order.pop_front();
  }
}

void KeyframeReassembly::AddKeyframe(AgentId agent, KeyframeData keyframe, KeyframeId reference_kf,
                                     Clock::time_point now) {
  AgentStreams& s = agents_[agent];
  s.keyframes.Note(keyframe.id.packed(), now, options_.seen_window);
  if (auto it = s.early.keyframes.find(keyframe.id.packed()); it != s.early.keyframes.end()) {
    ApplyPoseUpdate(it->second, &keyframe);
    s.early.keyframes.erase(it);
  }
  for (Held& h : s.held) {
    if (h.data.id != keyframe.id) continue;
    h.data = std::move(keyframe);  // a resend: the newer copy, in the original's place
    if (reference_kf.valid()) h.reference_kf = reference_kf;
    return;
  }
  s.held.push_back({std::move(keyframe), reference_kf, now});
}

void KeyframeReassembly::AddMapPoint(AgentId agent, MapPointData point, Clock::time_point now, BatchSet* out) {
  AgentStreams& s = agents_[agent];
  s.points.Note(point.id.packed(), now, options_.seen_window);
  if (auto it = s.early.points.find(point.id.packed()); it != s.early.points.end()) {
    point.reference_kf = it->second.reference_kf;
    point.position_ref = it->second.position_ref;
    s.early.points.erase(it);
  }
  const MapId segment = point.segment;
  out->For(agent, segment).map_points.push_back(std::move(point));
}

KeyframeReassembly::UpdateFate KeyframeReassembly::AddKeyframeUpdate(AgentId agent, const KeyframePoseUpdate& update,
                                                                     BatchSet* out) {
  AgentStreams& s = agents_[agent];
  if (!s.keyframes.Seen(update.id.packed(), update.id.counter())) {
    KeepEarly(&s.early.keyframes, update.id.packed(), update, options_.max_early_updates);
    return UpdateFate::kKeptEarly;
  }
  for (Held& h : s.held) {
    if (h.data.id != update.id) continue;
    ApplyPoseUpdate(update, &h.data);
    return UpdateFate::kAppliedToHeld;
  }
  out->For(agent, update.segment).keyframe_updates.push_back(update);
  return UpdateFate::kBatched;
}

KeyframeReassembly::UpdateFate KeyframeReassembly::AddMapPointUpdate(AgentId agent,
                                                                     const MapPointPositionUpdate& update,
                                                                     MapId segment, BatchSet* out) {
  AgentStreams& s = agents_[agent];
  if (!s.points.Seen(update.id.packed(), update.id.counter())) {
    KeepEarly(&s.early.points, update.id.packed(), update, options_.max_early_updates);
    return UpdateFate::kKeptEarly;
  }
  out->For(agent, segment).map_point_updates.push_back(update);
  return UpdateFate::kBatched;
}

bool KeyframeReassembly::Complete(AgentId agent, const AgentStreams& s, const KeyframeData& kf) const {
  return std::all_of(kf.point_links.begin(), kf.point_links.end(), [&](const auto& link) {
    const MapPointId mp = link.second;
    return mp.agent() != agent || s.points.Seen(mp.packed(), mp.counter());
  });
}

std::map<AgentId, int64_t> KeyframeReassembly::Release(Clock::time_point now, BatchSet* out) {
  std::map<AgentId, int64_t> incomplete;
  for (auto& [agent, s] : agents_) {
    while (!s.held.empty()) {
      Held& h = s.held.front();
      const bool complete = Complete(agent, s, h.data);
      if (!complete && now - h.since < options_.max_keyframe_hold) break;  // keep the agent's order
      if (!complete) ++incomplete[agent];
      h.data.points_incomplete = !complete;
      AgentBatch& b = out->For(agent, h.data.segment);
      if (h.reference_kf.valid()) b.reference_kf = h.reference_kf;
      b.keyframes.push_back(std::move(h.data));
      s.held.pop_front();
    }
  }
  return incomplete;
}

std::optional<KeyframeReassembly::Clock::time_point> KeyframeReassembly::NextDeadline() const {
  std::optional<Clock::time_point> next;
  for (const auto& [agent, s] : agents_) {
    if (s.held.empty()) continue;
    const Clock::time_point t = s.held.front().since + options_.max_keyframe_hold;
    if (!next || t < *next) next = t;
  }
  return next;
}

size_t KeyframeReassembly::held() const {
  size_t n = 0;
  for (const auto& [agent, s] : agents_) n += s.held.size();
  return n;
}

}  // namespace ccm::server
