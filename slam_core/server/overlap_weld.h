// Welding the whole overlap of two maps a fusion just joined. The verified detection merges
// the points around one keyframe pair; two agents
// that flew the same corridor for seconds share far more than that, and what is not merged
// is held by nothing but the one pair: the parts then rotate and scale about it in every
// later BA (a part accurate on its own, centimetres off under the map's one Sim(3)). Here
// every keyframe of one side looks for keyframes of the other side that see its scene (near
// it against its scene depth, looking the same way), and their points are projected into it
// and fused (map_ops/point_fusion) as the local merge does. Synchronous; the caller holds
// the map's structure lock.
#pragma once

#include <set>

#include "slam_core/map/map.h"
#include "slam_core/map_ops/point_fusion.h"

namespace ccm {

struct OverlapWeldOptions {
  /// A keyframe of the other side sees the same scene when its camera centre is within this
  /// share of the target's median scene depth and its optical axis within max_axis_deg.
  double max_centre_depth_ratio = 0.5;
  double max_axis_deg = 30.0;
  int max_sources = 4;        ///< nearest such keyframes whose points are projected
  double radius_px = 4.0;     ///< search radius around each projection
};

struct OverlapWeldReport {
  int targets = 0;  ///< keyframes of side a that had keyframes of the other side in view
  PointFusionResult fusion;
};

/// Projects the points of the map's other keyframes into the keyframes of side `a` (the
/// absorbed map's) that see the same scene and fuses them; connections of every touched
/// keyframe are updated.
OverlapWeldReport WeldOverlap(Map* map, const std::set<KeyframeId>& a, const OverlapWeldOptions& options = {});

}  // namespace ccm
