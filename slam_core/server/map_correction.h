// Essential-graph correction of a whole server map after a loop (ORB-SLAM's
// OptimizeEssentialGraph, CCM-SLAM 4.7): nodes are all keyframes as Sim(3); edges are the
// spanning tree, strong covisibility and loop edges measured from the poses before the loop
// correction, plus the new loop connections measured from the corrected poses; then every
// keyframe takes its optimized pose (scale folded into its position) and every point moves
// with its reference keyframe.
//
// Three steps so that the optimization needs no lock: BuildEssentialGraphProblem reads the
// map (the caller holds it), SolveEssentialGraph touches no map, ApplyCorrection writes the
// result as world-frame corrections (the caller holds the map exclusively), so keyframes and
// points added meanwhile follow their spanning-tree ancestor / reference keyframe.
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

/// The pose graph of a map, copied out of it (node ids are packed KeyframeIds): solvable
/// with no lock held.
using EssentialGraphProblem = opt::PoseGraphProblem;

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

EssentialGraphProblem BuildEssentialGraphProblem(const Map& map, const EssentialGraphCorrection& correction);
CorrectionResult SolveEssentialGraph(EssentialGraphProblem graph, const opt::PoseGraphOptions& options);

struct ApplyCorrectionReport {
  int keyframes = 0;
  int keyframes_added_meanwhile = 0;  ///< not in the graph; moved with their ancestor
  int points = 0;
};

/// Moves every keyframe by its correction D = S_opt * S_initial^-1 (p' = D * p for its
/// position, RigidPose for the pose), applied to its current pose: a keyframe in the graph
/// that did not move since the build ends exactly at its optimized pose. A keyframe added
/// since takes its spanning-tree ancestor's correction. Every point moves with the
/// correction of its point_reference override, else its reference keyframe (or that one's
/// ancestor), else its first corrected observer.
ApplyCorrectionReport ApplyCorrection(Map* map, const CorrectionResult& result);

}  // namespace ccm
