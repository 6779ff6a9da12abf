#include "slam_core/vo/local_map_bound.h"

#include <algorithm>
#include <vector>

namespace ccm {

std::string LocalMapBoundOptions::Validate() const {
  if (max_keyframes < 2) return "max_keyframes (N) must be >= 2";
  if (max_unacked_buffer < 0) return "max_unacked_buffer (B) must be >= 0";
  return "";
}

LocalMapBound::LocalMapBound(AgentId own_agent, LocalMapBoundOptions options)
    : own_agent_(own_agent), options_(options) {}

void LocalMapBound::OnKeyframeInserted(KeyframeId kf, bool from_server) {
  recency_.push_back(kf);
  if (from_server && kf.agent() == own_agent_) returned_.insert(kf);
}

bool LocalMapBound::EraseFromMap(Map* map, KeyframeId kf) {
  recency_.erase(std::remove(recency_.begin(), recency_.end(), kf), recency_.end());
  returned_.erase(kf);
  return map->EraseKeyframe(kf);
}

void LocalMapBound::Trim(Map* map, KeyframeId reference_kf, const AckSource& acks) {
  // Forget keyframes the map lost by other means (culling, server replacement).
  recency_.erase(std::remove_if(recency_.begin(), recency_.end(), [&](KeyframeId k) { return !map->keyframe(k); }),
                 recency_.end());
  for (auto it = returned_.begin(); it != returned_.end();) it = map->keyframe(*it) ? std::next(it) : returned_.erase(it);
  const auto server_has = [&](KeyframeId kf) { return kf.agent() != own_agent_ || returned_.count(kf) > 0; };
  const size_t n = static_cast<size_t>(options_.max_keyframes);
  // Candidates: everything except the reference and the N-1 most recent others.
  std::vector<KeyframeId> old;
  size_t recent_kept = 0;
  for (auto it = recency_.rbegin(); it != recency_.rend(); ++it) {
    if (*it == reference_kf) continue;
    if (recent_kept + 1 < n) {
      ++recent_kept;
      continue;
    }
    old.push_back(*it);
  }
  std::reverse(old.begin(), old.end());  // oldest first
  // Old own keyframes leave once the server has them for good; the others wait in the
  // buffer. Old foreign keyframes stay while there is room: they help tracking.
  std::vector<KeyframeId> processed, unacked;  // buffered, oldest first
  for (const KeyframeId kf : old) {
    if (server_has(kf)) continue;
    if (acks.IsPersisted(kf)) {
      if (EraseFromMap(map, kf)) ++stats_.removed_acked;
    } else {
      (acks.IsAcked(kf) ? processed : unacked).push_back(kf);
    }
  }
  const size_t limit = n + static_cast<size_t>(options_.max_unacked_buffer);
  size_t total = recency_.size();
  // Over N+B: first keyframes of other agents (the server has them; even recent ones,
  // since losing own data is worse), then the oldest processed but unsaved own ones (at
  // risk only if the server crashes), then the oldest unacknowledged own ones.
  std::vector<KeyframeId> foreign;
  for (const KeyframeId kf : recency_) {
    if (server_has(kf) && kf != reference_kf) foreign.push_back(kf);
  }
  for (const KeyframeId kf : foreign) {
    if (total <= limit) break;
    if (EraseFromMap(map, kf)) --total, ++stats_.removed_foreign;
  }
  for (const KeyframeId kf : processed) {
    if (total <= limit) break;
    if (EraseFromMap(map, kf)) --total, ++stats_.removed_unpersisted;
  }
  for (const KeyframeId kf : unacked) {
    if (total <= limit) break;
    if (EraseFromMap(map, kf)) --total, ++stats_.removed_lost;
  }
}

}  // namespace ccm
