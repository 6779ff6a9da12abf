// Map fusion (CCM-SLAM 4.8): two server maps that place recognition found overlapping
// become one. The smaller map is moved into the frame of the larger one with the verified
// Sim(3) (keyframes rigidly, points and positions scaled), its keyframes and points join the
// larger map, matched and duplicate points around the overlap are merged (optionally the
// whole overlap: overlap_weld.h), the overlap gets a loop edge, every handler of the absorbed
// map is re-pointed with its Sim(3) and scale composed, and the absorbed map leaves the stack.
// A global BA follows (the caller schedules it). Synchronous; takes both maps' structure
// locks exclusively (ascending map id).
#pragma once

#include <functional>
#include <string>

#include "slam_core/server/map_stack.h"
#include "slam_core/server/place_matcher.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct FusionReport {
  bool fused = false;
  std::string reason;
  MapId kept, absorbed;
  KeyframeId query, candidate;
  Sim3 kept_from_absorbed;
  int keyframes_moved = 0;
  int points_moved = 0;
  int points_merged = 0;
  int overlap_pairs = 0, overlap_inliers = 0;  ///< 3D-3D pairs of the overlap refinement
  bool refined = false;                        ///< the overlap refined the verified Sim(3)
  int weld_targets = 0, weld_merged = 0;       ///< the rest of the overlap (overlap_weld.h)
  double seconds = 0.0;
};

/// Fuses the maps of `detection` (kind kFusion). `on_fused(absorbed, kept)` runs while both
/// maps are still locked, so the database can be re-pointed before anyone queries it.
/// `weld_depth_ratio` > 0 welds the rest of the overlap (OverlapWeldOptions::max_centre_depth_ratio).
FusionReport FuseMaps(MapStack* stack, const PlaceDetection& detection, double weld_depth_ratio,
                      const std::function<void(MapId absorbed, MapId kept)>& on_fused);

}  // namespace ccm
