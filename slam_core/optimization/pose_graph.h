// 7-DoF Sim(3) pose-graph optimization over an essential graph (loop closure, map fusion),
// as in ORB-SLAM's OptimizeEssentialGraph: nodes are keyframe poses promoted to Sim(3) so
// that monocular scale drift can be corrected; edges are relative Sim(3) measurements
// (spanning tree, strong covisibility, loop edges). The caller builds the graph from its
// map, runs OptimizePoseGraph, then applies the corrections to keyframes (RigidPose) and
// map points (CorrectPointsByReference).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slam_core/geometry/se3.h"
#include "slam_core/geometry/sim3.h"
#include "slam_core/optimization/bundle_problem.h"

namespace ccm::opt {

struct Sim3Node {
  std::uint64_t id = 0;  ///< caller's keyframe id; not used by the solver
  /// World-from-camera similarity: p_w = s * R * p_c + t. Start from the keyframe's SE3 pose
  /// (s = 1), or from its loop-corrected Sim(3) for keyframes next to the loop.
  Sim3 world_from_cam;
  bool fixed = false;
};

enum class Sim3EdgeKind { kSpanningTree, kCovisibility, kLoop, kOther };

/// Relative measurement between nodes i and j: i_from_j = S_wi^-1 * S_wj, usually taken
/// from the uncorrected poses before the loop (so it holds the local geometry) or, for loop
/// edges, from the loop's Sim(3) estimate.
struct Sim3Edge {
  int i = 0;
  int j = 0;
  Sim3 i_from_j;
  /// Information multiplier for all 7 components (ORB-SLAM uses identity information).
  double weight = 1.0;
  Sim3EdgeKind kind = Sim3EdgeKind::kOther;
};

struct PoseGraphProblem {
  std::vector<Sim3Node> nodes;
  std::vector<Sim3Edge> edges;
};

struct PoseGraphOptions {
  int max_iterations = 20;  ///< ORB-SLAM runs 20 LM iterations
  int num_threads = 1;
  double function_tolerance = 1e-8;
  /// Nearly undamped start: on a 1000-node loop Ceres' default 1e4 needs 45 iterations,
  /// 1e8 needs 6 to the same cost (bench_optimization).
  double initial_trust_region_radius = 1e8;
  /// Gauge: if no node is fixed, node 0 is fixed (7-dof gauge).
  bool fix_first_node_if_none_fixed = true;
  std::string Validate() const;
};

/// The edge residual: [translation (3), rotation vector (3), log scale (1)] of
/// E = i_from_j_measured^-1 * S_wi^-1 * S_wj, times sqrt(weight). A local chart of
/// Sim(3) around identity, equal to the Sim(3) log to first order.
Eigen::Matrix<double, 7, 1> Sim3EdgeResidual(const Sim3& world_from_i, const Sim3& world_from_j,
                                              const Sim3Edge& edge);

/// Optimizes the non-fixed nodes in place. summary.inlier is empty (no outlier
/// classification in pose graphs); costs are over all edges.
OptimizationSummary OptimizePoseGraph(PoseGraphProblem* problem, const PoseGraphOptions& options = {});

/// Rigid keyframe pose of a corrected Sim(3) node: rotation and camera centre kept,
/// scale dropped (ORB-SLAM: Tcw = [R t/s]). Depths in that camera scale by s, which the
/// point correction below applies.
inline SE3 RigidPose(const Sim3& world_from_cam) {
  return SE3(world_from_cam.rotation(), world_from_cam.translation());
}

/// Corrects one map point with its reference keyframe's correction:
/// p_new = S_w_ref(optimized) * T_w_ref(before)^-1 * p_old.
inline Eigen::Vector3d CorrectPoint(const SE3& world_from_ref_before, const Sim3& world_from_ref_after,
                                    const Eigen::Vector3d& p_w) {
  return world_from_ref_after * (world_from_ref_before.inverse() * p_w);
}

/// Applies CorrectPoint to every point: reference_node[k] is the node index of point k's
/// reference keyframe (-1: leave the point unchanged), world_from_cam_before[n] the pose
/// of node n before the correction. Returns the number of points moved; 0 and no change
/// if the sizes do not match.
int CorrectPointsByReference(const std::vector<SE3>& world_from_cam_before, const PoseGraphProblem& optimized,
                             const std::vector<int>& reference_node, std::vector<Eigen::Vector3d>* points_w);

}  // namespace ccm::opt
