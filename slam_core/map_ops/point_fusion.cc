#include "slam_core/map_ops/point_fusion.h"

#include "slam_core/map_ops/keyframe_matching.h"

namespace ccm {

std::vector<std::shared_ptr<MapPoint>> PointsOf(const Map& map, const KeyFrame& kf) {
  std::vector<std::shared_ptr<MapPoint>> pts;
  for (const MapPointId id : kf.map_points()) {
    if (!id.valid()) continue;
    if (const auto mp = map.map_point(id); mp && !mp->bad()) pts.push_back(mp);
  }
  return pts;
}

KeypointGrid GridOf(const KeyFrame& kf) { return KeypointGrid(kf.features(), kf.camera().width(), kf.camera().height()); }

void FusePointsIntoKeyframe(Map* map, const std::shared_ptr<KeyFrame>& target, const KeypointGrid& grid,
                            const std::vector<std::shared_ptr<MapPoint>>& points, double radius_px,
                            PointFusionResult* result) {
  for (const auto& [mp, idx] : MatchPointsIntoKeyframe(*target, grid, points, radius_px)) {
    if (mp->bad() || !map->map_point(mp->id())) continue;
    const MapPointId existing = target->MapPointAt(idx);
    if (existing == mp->id()) continue;
    if (existing.valid()) {
      const auto other = map->map_point(existing);
      if (!other) continue;
      // Keep the better-supported point; the other one's observations move over.
      const bool keep_existing = other->num_observations() >= mp->num_observations();
      const MapPointId old_id = keep_existing ? mp->id() : existing;
      const MapPointId keep_id = keep_existing ? existing : mp->id();
      if (map->ReplaceMapPoint(old_id, keep_id)) {
        ++result->fused;
        result->replaced.emplace_back(old_id, keep_id);
      }
    } else if (!mp->KeypointIn(target->id())) {
      if (map->AddObservation(target->id(), idx, mp->id())) ++result->linked;
    }
  }
}

}  // namespace ccm
