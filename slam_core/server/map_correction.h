// Essential-graph correction of a whole server map after a loop (ORB-SLAM's
// OptimizeEssentialGraph, CCM-SLAM 4.7): nodes are all keyframes as Sim(3); edges are the
// spanning tree, strong covisibility and loop edges measured from the poses before the loop
// correction, plus the new loop connections measured from the corrected poses; then every
// keyframe takes its optimized pose (scale folded into its position) and every point moves
// with its reference keyframe. Synchronous; the caller holds the map exclusively.
#pragma once

#include <unordered_map>
#include <utility>
#include <vector>

#include "slam_core/map/map.h"
#include "slam_core/optimization/pose_graph.h"

namespace ccm {

struct EssentialGraphCorrection {
  std::unordered_map<KeyframeId, SE3> before;      ///< every keyframe's pose before the loop correction
  std::unordered_map<KeyframeId, Sim3> corrected;  ///< initial Sim(3) of the keyframes moved by the loop
  std::vector<std::pair<KeyframeId, KeyframeId>> loop_connections;
  KeyframeId fixed;                                ///< gauge (the loop candidate)
};

struct CorrectionResult {
  bool ok = false;
  int nodes = 0, edges = 0, iterations = 0;
  double seconds = 0.0;
  std::unordered_map<KeyframeId, Sim3> initial;    ///< Sim(3) the points are currently consistent with
  std::unordered_map<KeyframeId, Sim3> optimized;
  /// Points whose position is consistent with another keyframe than their reference one
  /// (moved with the loop neighbourhood): that keyframe's correction applies to them.
  std::unordered_map<MapPointId, KeyframeId> point_reference;
};

CorrectionResult OptimizeEssentialGraph(const Map& map, const EssentialGraphCorrection& correction,
                                        const opt::PoseGraphOptions& options);

/// Writes the optimized poses and moves every point with its reference keyframe (the
/// point_reference override, else its reference, else its first observer):
/// p' = S_opt(ref) * S_initial(ref)^-1 * p.
void ApplyCorrection(Map* map, const CorrectionResult& result);

}  // namespace ccm
