#include "server_runtime/downlink_deltas.h"

#include <algorithm>

namespace ccm::server {

void DownlinkDeltas::OnHoldings(const ServerHoldings& holdings) {
  if (holdings.applied_stamp_ns == 0) return;  // nothing integrated yet
  reports_ = true;
  held_ = std::unordered_set<KeyframeId>(holdings.keyframes.begin(), holdings.keyframes.end());
  while (!sent_since_.empty() && sent_since_.front().first <= holdings.applied_stamp_ns) sent_since_.pop_front();
}

std::unordered_set<KeyframeId> DownlinkDeltas::HeldKeyframes() const {
  if (!reports_) return {};
  std::unordered_set<KeyframeId> held = held_;
  for (const auto& [stamp, ids] : sent_since_) held.insert(ids.begin(), ids.end());
  return held;
}

void DownlinkDeltas::MarkHeldPoints(ServerMapData* data) const {
  if (!reports_) return;
  std::unordered_set<KeyframeId> full;
  for (const ServerKeyframe& kf : data->keyframes) {
    if (!kf.held) full.insert(kf.id);
  }
  for (ServerMapPoint& mp : data->map_points) {
    // Seen by a keyframe going in full: the agent may have dropped the point with it.
    const bool seen_by_full = std::any_of(mp.observations.begin(), mp.observations.end(),
                                          [&](const auto& o) { return full.count(o.first) > 0; });
    mp.held = !seen_by_full && points_sent_.count(mp.id) > 0;
  }
}

void DownlinkDeltas::RecordSent(int64_t stamp_ns, const ServerMapData& data) {
  if (!reports_) return;
  while (!sent_since_.empty() && sent_since_.front().first < stamp_ns - kInFlightNs) sent_since_.pop_front();
  std::vector<KeyframeId> full;
  for (const ServerKeyframe& kf : data.keyframes) {
    if (!kf.held) full.push_back(kf.id);
  }
  if (!full.empty()) sent_since_.emplace_back(stamp_ns, std::move(full));
  for (const ServerMapPoint& mp : data.map_points) {
    if (!mp.held) {
      points_sent_[mp.id] = stamp_ns;
    } else if (const auto it = points_sent_.find(mp.id); it != points_sent_.end()) {
      it->second = stamp_ns;
    }
  }
  if (stamp_ns - last_prune_ns_ >= kForgetPointNs / 6) {  // a pass over the set every 10 s
    last_prune_ns_ = stamp_ns;
    for (auto it = points_sent_.begin(); it != points_sent_.end();) {
      it = it->second < stamp_ns - kForgetPointNs ? points_sent_.erase(it) : std::next(it);
    }
  }
}

}  // namespace ccm::server
