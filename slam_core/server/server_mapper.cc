#include "slam_core/server/server_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include "slam_core/map/near_duplicate.h"
#include "slam_core/map_ops/map_bundle_adjustment.h"
#include "slam_core/map_ops/point_fusion.h"

namespace ccm {

ServerMappingReport ServerMapper::Process(ServerMap* smap, const std::shared_ptr<KeyFrame>& kf) const {
  ServerMappingReport r;
  Map& map = smap->map();
  const auto t0 = std::chrono::steady_clock::now();
  map.UpdateConnections(kf->id());
  FuseWithNeighbourhood(smap, kf, &r);
  const auto t1 = std::chrono::steady_clock::now();
  r.fusion_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  // The agent already optimized the keyframe with everything it knew; a local BA pays off
  // only where the server just associated points the agent did not have.
  const bool new_links = r.points_fused + r.observations_linked >= options_.local_ba_min_new_associations;
  if (options_.local_ba && new_links && NeedsLocalBa(*kf)) {
    std::vector<std::shared_ptr<KeyFrame>> window{kf};
    for (const KeyframeId id : kf->BestCovisible(options_.local_ba_window - 1)) {
      if (const auto n = map.keyframe(id); n && !n->bad()) window.push_back(n);
    }
    opt::BundleAdjusterOptions ba = opt::LocalBaDefaults();
    ba.num_threads = 1;
    ba.robust_iterations = options_.local_ba_robust_iterations;
    ba.refine_iterations = options_.local_ba_refine_iterations;
    // Appearance only where observations changed: positions move by millimetres here.
    const MapBaReport rep =
        BundleAdjustKeyframes(&map, window, options_.local_ba_max_fixed, ba, true, nullptr, /*update_appearance=*/false);
    r.local_ba = rep.summary.usable;
    if (r.local_ba) {
      std::vector<KeyframeId> ids;
      for (const auto& k : window) ids.push_back(k->id());
      smap->MarkSettled(ids);
    }
    r.local_ba_outliers = rep.outliers_removed;
    map.UpdateConnections(kf->id());
    r.local_ba_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
  }
  if (options_.duplicate_distance_ratio > 0.0) {
    const KeyframeId dup = NearDuplicateOf(map, *kf);
    // The duplicate may have been erased since (redundancy step, another agent's mapping).
    if (const auto base = dup.valid() ? map.keyframe(dup) : nullptr) {
      smap->AddAnchor(kf->id(), {dup, base->cam_from_world() * kf->world_from_cam(), kf->stamp_ns(),
                                 smap->Info(kf->id()) ? smap->Info(kf->id())->segment : MapId()});
      map.EraseKeyframe(kf->id());
      smap->EraseInfo(kf->id());
      r.skipped = true;
      r.duplicate_of = dup;
    }
  }
  return r;
}

void ServerMapper::FuseWithNeighbourhood(ServerMap* smap, const std::shared_ptr<KeyFrame>& kf,
                                         ServerMappingReport* r) const {
  Map& map = smap->map();
  std::vector<KeyframeId> targets;
  std::set<KeyframeId> seen{kf->id()};
  const auto first = kf->BestCovisible(options_.fusion_neighbours);
  for (const KeyframeId id : first) {
    if (seen.insert(id).second) targets.push_back(id);
  }
  for (const KeyframeId id : first) {
    const auto n = map.keyframe(id);
    if (!n) continue;
    for (const KeyframeId id2 : n->BestCovisible(5)) {
      if (seen.insert(id2).second) targets.push_back(id2);
    }
  }
  PointFusionResult fusion;
  const auto own = PointsOf(map, *kf);
  for (const KeyframeId t : targets) {
    if (const auto target = map.keyframe(t)) {
      FusePointsIntoKeyframe(&map, target, GridOf(*target), own, options_.fusion_radius_px, &fusion);
    }
  }
  const KeypointGrid grid = GridOf(*kf);
  for (const KeyframeId t : targets) {
    if (const auto target = map.keyframe(t)) {
      FusePointsIntoKeyframe(&map, kf, grid, PointsOf(map, *target), options_.fusion_radius_px, &fusion);
    }
  }
  for (const auto& [old_id, keep] : fusion.replaced) smap->RecordReplacement(old_id, keep);
  for (const auto& mp : PointsOf(map, *kf)) map.UpdateMapPointAppearance(mp->id());
  map.UpdateConnections(kf->id());
  r->points_fused += fusion.fused;
  r->observations_linked += fusion.linked;
}

bool ServerMapper::NeedsLocalBa(const KeyFrame& kf) const {
  for (const KeyframeId n : kf.BestCovisible(-1)) {
    if (n.agent() != kf.agent()) return true;
    if (n.counter() + static_cast<uint64_t>(options_.recent_keyframes) < kf.id().counter()) return true;
  }
  return false;
}

KeyframeId ServerMapper::NearDuplicateOf(const Map& map, const KeyFrame& kf) const {
  NearDuplicateRule rule;
  rule.distance_ratio = options_.duplicate_distance_ratio;
  rule.max_angle_deg = options_.duplicate_max_angle_deg;
  return ccm::NearDuplicateOf(map, kf, rule);
}

}  // namespace ccm
