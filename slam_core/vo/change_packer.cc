#include "slam_core/vo/change_packer.h"

#include <algorithm>
#include <limits>

namespace ccm {
namespace {

bool Excluded(const KeyframeFilter& excluded, KeyframeId id) { return excluded && excluded(id); }

// The newest keyframe of the same agent older than `id` still in the map.
KeyframeId PredecessorOf(const Map& map, KeyframeId id, const KeyframeFilter& excluded) {
  KeyframeId best;
  for (const auto& kf : map.keyframes()) {  // sorted by id
    if (!(kf->id() < id)) break;
    if (kf->agent() == id.agent() && !kf->bad() && !Excluded(excluded, kf->id())) best = kf->id();
  }
  return best;
}

KeyframeId ParentOf(const Map& map, const KeyFrame& kf, const KeyframeFilter& excluded) {
  KeyframeId parent = kf.parent();
  if (!parent.valid() || !map.keyframe(parent) || Excluded(excluded, parent)) {
    parent = KeyframeId::Invalid();
    for (const KeyframeId id : kf.BestCovisible(3)) {
      if (!Excluded(excluded, id)) return id;
    }
  }
  return parent;
}

// `excluded`: keyframes sent as anchors. Nothing is placed relative to an anchor: its pose
// on the server is its VO pose when sent, never updated, and a chain of keyframes hung on
// it would inherit that error. (Measured on the repeated hall: no difference either way;
// the rule keeps anchors leaves of the server's pose chains.)
void FillRelative(const Map& map, const KeyFrame& kf, const KeyframeFilter& excluded, KeyframeId* pred,
                  SE3* pred_from_cam, KeyframeId* parent, SE3* parent_from_cam) {
  const SE3 world_from_cam = kf.world_from_cam();
  *pred = PredecessorOf(map, kf.id(), excluded);
  if (const auto p = pred->valid() ? map.keyframe(*pred) : nullptr) {
    *pred_from_cam = p->cam_from_world() * world_from_cam;
  } else {
    *pred = KeyframeId::Invalid();
  }
  *parent = ParentOf(map, kf, excluded);
  if (const auto p = parent->valid() ? map.keyframe(*parent) : nullptr) {
    *parent_from_cam = p->cam_from_world() * world_from_cam;
  } else {
    *parent = KeyframeId::Invalid();
  }
}

}  // namespace

std::optional<KeyframeData> PackKeyframe(const Map& map, KeyframeId id, const KeyframeFilter& excluded) {
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
  FillRelative(map, *kf, excluded, &d.predecessor, &d.pred_from_cam, &d.parent, &d.parent_from_cam);
  d.segment_from_cam = kf->world_from_cam();
  return d;
}

std::optional<MapPointData> PackMapPoint(const Map& map, MapPointId id,
                                         const KeyframeFilter& excluded) {
  const auto mp = map.map_point(id);
  if (!mp || mp->bad()) return std::nullopt;
  MapPointData d;
  d.id = id;
  d.segment = map.id();
  d.descriptor = mp->descriptor();
  for (const auto& [kf, idx] : mp->observations()) {
    if (kf.agent() == id.agent() && map.keyframe(kf) && !(excluded && excluded(kf))) d.observations.emplace_back(kf, idx);
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
    anchored_.clear();
    sent_links_.clear();
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
  if (options_.new_keyframe_delay_s > 0.0 && !flush) {
    for (const auto& kf : map.keyframes()) {
      if (kf->agent() == agent_) newest_ns = std::max(newest_ns, kf->stamp_ns());
    }
  }
  const auto too_young = [&](const KeyFrame& kf) {
    return newest_ns > 0 && static_cast<double>(newest_ns - kf.stamp_ns()) * 1e-9 < options_.new_keyframe_delay_s;
  };
  // A resent keyframe goes with its own points in full: whatever kept the server from
  // acknowledging the keyframe (a dropped batch, a restarted server) may have lost them too.
  std::set<MapPointId> points = changes.map_points, resend_points;
  points.insert(deferred_points_.begin(), deferred_points_.end());
  deferred_points_.clear();
  const KeyframeFilter is_anchor = [this](KeyframeId kf) { return IsAnchor(kf); };
  std::vector<KeyframeId> updated;  // packed after the new ones: they may become anchors
  for (const KeyframeId id : kfs) {
    if (id.agent() != agent_ || FromServer(map, id)) continue;  // the server has those
    const bool full = resend_.count(id) || !sent_kfs_.count(id);
    if (full) {
      if (!resend_.count(id)) {
        const auto kf = map.keyframe(id);
        if (kf && too_young(*kf)) {
          deferred_kfs_.insert(id);
          continue;
        }
      }
      if (auto d = PackNew(map, id, resend_.count(id) > 0)) {
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
    updated.push_back(id);
  }
  // Links are settled once every keyframe of this batch is known as sent.
  for (KeyframeData& d : batch.keyframes) {
    if (d.anchor_only) continue;
    if (!resend_.count(d.id)) DropLinksToLaterPoints(map, &d);
    auto& links = sent_links_[d.id];
    for (const auto& link : d.point_links) links.insert(link.second);
  }
  for (const KeyframeId id : updated) {
    const auto kf = map.keyframe(id);
    if (!kf || IsAnchor(id)) continue;  // the server ignores updates of anchors
    KeyframePoseUpdate u;
    u.id = id;
    u.segment = map.id();
    FillRelative(map, *kf, is_anchor, &u.predecessor, &u.pred_from_cam, &u.parent, &u.parent_from_cam);
    batch.keyframe_updates.push_back(u);
  }
  resend_.clear();
  points.insert(resend_points.begin(), resend_points.end());
  for (const MapPointId id : points) {
    if (id.agent() != agent_) continue;
    if (const auto mp = map.map_point(id); mp && mp->from_server()) continue;  // sent back: the server has it
    auto d = PackMapPoint(map, id, is_anchor);
    if (!d) continue;
    auto sent = sent_points_.find(id);
    if (sent == sent_points_.end() && d->reference_kf.agent() == agent_ && !sent_kfs_.count(d->reference_kf) &&
        !FromServer(map, d->reference_kf)) {
      deferred_points_.insert(id);  // its reference keyframe has not left yet
      continue;
    }
    if (sent == sent_points_.end() || resend_points.count(id)) {
      if (!resend_points.count(id)) OmitLinkedObservations(&*d);
      sent_points_[id] = {d->reference_kf, d->position_ref};
      batch.map_points.push_back(std::move(*d));
      ++points_sent_;
    } else if (sent->second.reference_kf != d->reference_kf ||
               (d->position_ref - sent->second.position_ref).norm() >
                   options_.min_point_update_ratio * sent->second.position_ref.norm()) {
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

void ChangePacker::OmitLinkedObservations(MapPointData* mp) const {
  // The server attaches a keyframe's links to points it does not have yet once the point
  // arrives (AgentRegistration), so an observation needs to travel with the point only if
  // no keyframe link carries it: a keyframe sent before it observed the point, or sent
  // before the point left (DropLinksToLaterPoints). Keyframes still to be sent carry it in
  // their links. (A resent point keeps all: the server that lost it may have lost the links
  // too.) ~10 B per observation, ~4 per point.
  auto& obs = mp->observations;
  obs.erase(std::remove_if(obs.begin(), obs.end(),
                           [&](const auto& o) {
                             if (!sent_kfs_.count(o.first)) return true;
                             const auto it = sent_links_.find(o.first);
                             return it != sent_links_.end() && it->second.count(mp->id) > 0;
                           }),
            obs.end());
}

void ChangePacker::DropLinksToLaterPoints(const Map& map, KeyframeData* kf) const {
  // A keyframe leaves new_keyframe_delay_s after it was made; by then it also observes
  // points that younger keyframes created, and those wait for their own reference keyframe
  // (deferred_points_). The server holds a keyframe until the own points it links arrive
  // (up to 1.5 s): with those links, 40 % of the keyframes waited the full hold on a
  // perfect link. Without them the observation travels with the point instead
  // (OmitLinkedObservations keeps what no sent link carries). Called when every keyframe
  // of the batch is in sent_kfs_, so points that leave in the same batch keep their links.
  // (The point's own reference is an approximation of PackMapPoint's choice, which skips
  // anchors: a miss only costs the server's bounded hold.)
  auto& links = kf->point_links;
  links.erase(std::remove_if(links.begin(), links.end(),
                             [&](const auto& link) {
                               const MapPointId mp_id = link.second;
                               if (mp_id.agent() != agent_ || sent_points_.count(mp_id)) return false;
                               const auto mp = map.map_point(mp_id);
                               if (!mp) return false;
                               const KeyframeId ref = mp->reference_kf();
                               return ref != kf->id && !sent_kfs_.count(ref) && !FromServer(map, ref);
                             }),
              links.end());
}

bool ChangePacker::FromServer(const Map& map, KeyframeId id) {
  const auto kf = map.keyframe(id);
  return kf && kf->from_server();
}

bool ChangePacker::ServerHasInFull(KeyframeId id) const {
  return id.agent() != agent_ || (sent_kfs_.count(id) > 0 && !IsAnchor(id));
}

std::optional<KeyframeData> ChangePacker::PackNew(const Map& map, KeyframeId id, bool resend) {
  const auto kf = map.keyframe(id);
  if (!kf) return std::nullopt;
  KeyframeId dup;
  if (resend) {
    // Resent as what it was sent as, while the keyframe it duplicates is still here.
    const auto it = anchored_.find(id);
    if (it != anchored_.end() && map.keyframe(it->second)) dup = it->second;
  } else if (options_.anchor_duplicates.enabled()) {
    // Observers: keyframes the server has in full and own keyframes still to be sent (most go
    // in full: an anchor must be within a few centimetres of a full keyframe, so anchors
    // never follow each other for long). Counting only what is already sent would miss
    // most duplicates: at 1.5 s old a keyframe's points are ~25 % seen by younger keyframes.
    dup = NearDuplicateOf(
        map, *kf, options_.anchor_duplicates,
        [this, &map](KeyframeId k) { return ServerHasInFull(k) || FromServer(map, k); },
        [this](KeyframeId k) { return !IsAnchor(k); });
  }
  auto d = PackKeyframe(map, id, [this](KeyframeId k) { return IsAnchor(k); });
  const auto base = dup.valid() ? map.keyframe(dup) : nullptr;
  if (!d || !base) {
    const bool was_anchor = anchored_.erase(id) > 0;
    if (d && resend && was_anchor) ++anchors_resent_in_full_;
    return d;
  }
  d->anchor_only = true;
  d->features = std::make_shared<const FrameFeatures>();
  d->point_links.clear();
  d->parent = dup;
  d->parent_from_cam = base->cam_from_world() * kf->world_from_cam();
  anchored_[id] = dup;
  if (!resend) ++anchors_sent_;  // first transmissions only, as the server counts them
  return d;
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
  for (auto it = sent_links_.begin(); it != sent_links_.end();) {
    it = map.keyframe(it->first) ? std::next(it) : sent_links_.erase(it);
  }
  for (auto it = anchored_.begin(); it != anchored_.end();) {
    it = map.keyframe(it->first) ? std::next(it) : anchored_.erase(it);
  }
  for (auto it = sent_points_.begin(); it != sent_points_.end();) {
    it = map.map_point(it->first) ? std::next(it) : sent_points_.erase(it);
  }
}

}  // namespace ccm
