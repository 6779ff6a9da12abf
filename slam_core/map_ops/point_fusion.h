// Fusion of duplicate map points by projection, shared by the agent's local mapping and the
// server's mapping, loop closing and map fusion: points are projected into a keyframe and
// matched to its keypoints; a keypoint that already has another point keeps the point with
// more observations (the other one's observations move over), a free keypoint gains an
// observation. Synchronous; works on the map through its thread-safe accessors.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/map/map.h"

namespace ccm {

struct PointFusionResult {
  int fused = 0;   ///< duplicate pairs merged
  int linked = 0;  ///< observations added to free keypoints
  /// (replaced point, point that now stands for it), in merge order.
  std::vector<std::pair<MapPointId, MapPointId>> replaced;
};

/// The good (present, not bad) points `kf` observes.
std::vector<std::shared_ptr<MapPoint>> PointsOf(const Map& map, const KeyFrame& kf);
/// Grid over a keyframe's keypoints for radius queries.
KeypointGrid GridOf(const KeyFrame& kf);

/// Projects `points` into `target` (with its current pose) and fuses them as described above.
/// Results accumulate into *result.
void FusePointsIntoKeyframe(Map* map, const std::shared_ptr<KeyFrame>& target, const KeypointGrid& grid,
                            const std::vector<std::shared_ptr<MapPoint>>& points, double radius_px,
                            PointFusionResult* result);

}  // namespace ccm
