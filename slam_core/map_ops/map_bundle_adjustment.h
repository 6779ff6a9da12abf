// Bridges the map and the map-agnostic optimizers: copies keyframes, points and
// observations into an opt::BundleProblem, runs bundle adjustment and writes poses,
// positions and outlier removals back. Used by initialization and local mapping.
#pragma once

#include <memory>
#include <vector>

#include "slam_core/map/map.h"
#include "slam_core/map_ops/change_log.h"
#include "slam_core/optimization/bundle_adjustment.h"

namespace ccm {

struct MapBaReport {
  opt::OptimizationSummary summary;
  int num_free_keyframes = 0;
  int num_fixed_keyframes = 0;
  int num_points = 0;
  int outliers_removed = 0;
};

/// Optimizes `free_kfs` and every point they observe; other keyframes observing those
/// points enter as fixed (at most max_fixed of them, most observations first).
/// With remove_outliers, observations flagged as outliers are erased from the map. With
/// update_appearance every optimized point's descriptor, normal and depth range are
/// recomputed (the VO tracks with them); otherwise only those that lost an observation.
MapBaReport BundleAdjustKeyframes(Map* map, const std::vector<std::shared_ptr<KeyFrame>>& free_kfs,
                                  int max_fixed, const opt::BundleAdjusterOptions& options,
                                  bool remove_outliers, ChangeLog* changes, bool update_appearance = true);

/// `kf`'s links to good map points as pose-only observations (point position, keypoint,
/// sigma of its level), for opt::OptimizePose; `points` (if given) gets the linked point ids
/// in the same order.
std::vector<opt::PointObservation> LinkedPointObservations(const Map& map, const KeyFrame& kf,
                                                           std::vector<MapPointId>* points = nullptr);

}  // namespace ccm
