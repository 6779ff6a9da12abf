#include "slam_core/vo/change_packer.h"

#include <algorithm>
#include <limits>

namespace ccm {
namespace {

// The newest keyframe of the same agent older than `id` still in the map.
KeyframeId PredecessorOf(const Map& map, KeyframeId id) {
  KeyframeId best;
  for (const auto& kf : map.keyframes()) {  // sorted by id
    if (!(kf->id() < id)) break;
    if (kf->agent() == id.agent() && !kf->bad()) best = kf->id();
  }
  return best;
}

KeyframeId ParentOf(const Map& map, const KeyFrame& kf) {
  KeyframeId parent = kf.parent();
  if (!parent.valid() || !map.keyframe(parent)) {
    const auto best = kf.BestCovisible(1);
    parent = best.empty() ? KeyframeId::Invalid() : best.front();
  }
  return parent;
}

void FillRelative(const Map& map, const KeyFrame& kf, KeyframeId* pred, SE3* pred_from_cam, KeyframeId* parent,
                  SE3* parent_from_cam) {
  const SE3 world_from_cam = kf.world_from_cam();
  *pred = PredecessorOf(map, kf.id());
  if (const auto p = pred->valid() ? map.keyframe(*pred) : nullptr) {
    *pred_from_cam = p->cam_from_world() * world_from_cam;
  } else {
    *pred = KeyframeId::Invalid();
  }
  *parent = ParentOf(map, kf);
  if (const auto p = parent->valid() ? map.keyframe(*parent) : nullptr) {
    *parent_from_cam = p->cam_from_world() * world_from_cam;
  } else {
    *parent = KeyframeId::Invalid();
  }
}

}  // namespace

std::optional<KeyframeData> PackKeyframe(const Map& map, KeyframeId id) {
  const auto kf = map.keyframe(id);
  if (!kf) return std::nullopt;
  KeyframeData d;
  d.id = id;
  d.segment = map.id();
  d.stamp_ns = kf->stamp_ns();
  d.camera = kf->camera_ptr();
  d.pyramid_levels = kf->pyramid().num_levels;
  d.pyramid_scale_factor = kf->pyramid().scale_factor;
  d.features = kf->features_ptr();
  const auto mps = kf->map_points();
  for (size_t i = 0; i < mps.size(); ++i) {
    if (mps[i].valid()) d.point_links.emplace_back(static_cast<int>(i), mps[i]);
  }
  FillRelative(map, *kf, &d.predecessor, &d.pred_from_cam, &d.parent, &d.parent_from_cam);
  d.segment_from_cam = kf->world_from_cam();
  return d;
}

std::optional<MapPointData> PackMapPoint(const Map& map, MapPointId id) {
  const auto mp = map.map_point(id);
  if (!mp || mp->bad()) return std::nullopt;
  MapPointData d;
  d.id = id;
  d.segment = map.id();
  d.descriptor = mp->descriptor();
  for (const auto& [kf, idx] : mp->observations()) {
    if (kf.agent() == id.agent() && map.keyframe(kf)) d.observations.emplace_back(kf, idx);
  }
  if (d.observations.empty()) return std::nullopt;
  KeyframeId ref = mp->reference_kf();
  if (!std::any_of(d.observations.begin(), d.observations.end(), [&](const auto& o) { return o.first == ref; })) {
    ref = d.observations.front().first;
  }
  const auto ref_kf = map.keyframe(ref);
  if (!ref_kf) return std::nullopt;
  d.reference_kf = ref;
  d.position_ref = ref_kf->cam_from_world() * mp->position();
  return d;
}

AgentBatch ChangePacker::Pack(const VoChanges& changes, int64_t stamp_ns) {
  AgentBatch batch;
  batch.agent = agent_;
  batch.stamp_ns = stamp_ns;
  batch.reference_kf = changes.reference_kf;
  if (!changes.map) return batch;
  const Map& map = *changes.map;
  batch.segment = map.id();
  if (map.id() != segment_) {
    // A new segment: its keyframes and points are all new; the old ones will not change again.
    segment_ = map.id();
    sent_kfs_.clear();
    sent_points_.clear();
    deferred_kfs_.clear();
    deferred_points_.clear();
  }
  const bool flush = flush_;
  flush_ = false;
  std::set<KeyframeId> kfs = changes.keyframes;
  kfs.insert(resend_.begin(), resend_.end());
  kfs.insert(deferred_kfs_.begin(), deferred_kfs_.end());
  deferred_kfs_.clear();
  // Data time of the newest own keyframe: the age of a new keyframe for the send delay.
  int64_t newest_ns = 0;
  if (new_keyframe_delay_s_ > 0.0 && !flush) {
    for (const auto& kf : map.keyframes()) {
      if (kf->agent() == agent_) newest_ns = std::max(newest_ns, kf->stamp_ns());
    }
  }
  const auto too_young = [&](const KeyFrame& kf) {
    return newest_ns > 0 && static_cast<double>(newest_ns - kf.stamp_ns()) * 1e-9 < new_keyframe_delay_s_;
  };
  // A resent keyframe goes with its own points in full: whatever kept the server from
  // acknowledging the keyframe (a dropped batch, a restarted server) may have lost them too.
  std::set<MapPointId> points = changes.map_points, resend_points;
  points.insert(deferred_points_.begin(), deferred_points_.end());
  deferred_points_.clear();
  for (const KeyframeId id : kfs) {
    if (id.agent() != agent_) continue;
    const bool full = resend_.count(id) || !sent_kfs_.count(id);
    if (full) {
      if (!resend_.count(id)) {
        const auto kf = map.keyframe(id);
        if (kf && too_young(*kf)) {
          deferred_kfs_.insert(id);
          continue;
        }
      }
      if (auto d = PackKeyframe(map, id)) {
        if (resend_.count(id)) {
          for (const auto& link : d->point_links) {
            if (link.second.agent() == agent_) resend_points.insert(link.second);
          }
        }
        batch.keyframes.push_back(std::move(*d));
        sent_kfs_.insert(id);
        ++keyframes_sent_;
      }
      continue;
    }
    const auto kf = map.keyframe(id);
    if (!kf) continue;
    KeyframePoseUpdate u;
    u.id = id;
    u.segment = map.id();
    FillRelative(map, *kf, &u.predecessor, &u.pred_from_cam, &u.parent, &u.parent_from_cam);
    batch.keyframe_updates.push_back(u);
  }
  resend_.clear();
  points.insert(resend_points.begin(), resend_points.end());
  for (const MapPointId id : points) {
    if (id.agent() != agent_) continue;
    auto d = PackMapPoint(map, id);
    if (!d) continue;
    auto sent = sent_points_.find(id);
    if (sent == sent_points_.end() && d->reference_kf.agent() == agent_ && !sent_kfs_.count(d->reference_kf)) {
      deferred_points_.insert(id);  // its reference keyframe has not left yet
      continue;
    }
    if (sent == sent_points_.end() || resend_points.count(id)) {
      sent_points_[id] = {d->reference_kf, d->position_ref};
      batch.map_points.push_back(std::move(*d));
      ++points_sent_;
    } else if (sent->second.reference_kf != d->reference_kf ||
               (d->position_ref - sent->second.position_ref).norm() >
                   min_point_update_ratio_ * sent->second.position_ref.norm()) {
      sent->second = {d->reference_kf, d->position_ref};
      batch.map_point_updates.push_back({id, d->reference_kf, d->position_ref});
    } else {
      ++point_updates_skipped_;
    }
  }
  batch.reference_kf = SharedReference(map, changes.reference_kf);
  if (++packs_ % 64 == 0) Forget(map);
  return batch;
}

KeyframeId ChangePacker::SharedReference(const Map& map, KeyframeId vo_reference) const {
  // The server answers relative to the reference keyframe, so it must have it: the VO's
  // reference is usually younger than the send delay and not at the server yet (then the
  // server could place nothing and map sharing never happened). Use the newest keyframe
  // already sent; it is at most the send delay older.
  if (!vo_reference.valid() || sent_kfs_.count(vo_reference)) return vo_reference;
  KeyframeId best = vo_reference;
  int64_t best_ns = std::numeric_limits<int64_t>::min();
  for (const KeyframeId id : sent_kfs_) {
    const auto kf = map.keyframe(id);
    if (kf && !kf->bad() && kf->stamp_ns() > best_ns) best = id, best_ns = kf->stamp_ns();
  }
  return best;
}

void ChangePacker::Forget(const Map& map) {
  // Ids that left the local map never change again: keep the sets bounded on long flights.
  for (auto it = sent_kfs_.begin(); it != sent_kfs_.end();) it = map.keyframe(*it) ? std::next(it) : sent_kfs_.erase(it);
  for (auto it = sent_points_.begin(); it != sent_points_.end();) {
    it = map.map_point(it->first) ? std::next(it) : sent_points_.erase(it);
  }
}

}  // namespace ccm
