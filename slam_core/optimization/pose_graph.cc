#include "slam_core/optimization/pose_graph.h"

#include <chrono>
#include <memory>

#include <ceres/problem.h>
#include <ceres/solver.h>

#include "slam_core/optimization/pose_graph_cost.h"
#include "slam_core/optimization/pose_manifold.h"

namespace ccm::opt {

std::string PoseGraphOptions::Validate() const {
  if (max_iterations < 1) return "max_iterations must be >= 1";
  if (num_threads < 1) return "num_threads must be >= 1";
  if (!(function_tolerance > 0.0)) return "function_tolerance must be > 0";
  if (!(initial_trust_region_radius > 0.0)) return "initial_trust_region_radius must be > 0";
  return "";
}

Eigen::Matrix<double, 7, 1> Sim3EdgeResidual(const Sim3& world_from_i, const Sim3& world_from_j,
                                              const Sim3Edge& edge) {
  const Sim3Block a = PackSim3(world_from_i);
  const Sim3Block b = PackSim3(world_from_j);
  Eigen::Matrix<double, 7, 1> r;
  Sim3EdgeError(edge.i_from_j, edge.weight)(a.data(), b.data(), r.data());
  return r;
}

namespace {

std::string ValidateGraph(const PoseGraphProblem& g) {
  const int n = static_cast<int>(g.nodes.size());
  for (size_t k = 0; k < g.edges.size(); ++k) {
    const Sim3Edge& e = g.edges[k];
    if (e.i < 0 || e.i >= n || e.j < 0 || e.j >= n || e.i == e.j) {
      return "edge " + std::to_string(k) + " has invalid node indices";
    }
    if (!(e.weight > 0.0)) return "edge " + std::to_string(k) + " has weight <= 0";
    if (!(e.i_from_j.scale() > 0.0)) return "edge " + std::to_string(k) + " has scale <= 0";
  }
  for (size_t k = 0; k < g.nodes.size(); ++k) {
    if (!(g.nodes[k].world_from_cam.scale() > 0.0)) return "node " + std::to_string(k) + " has scale <= 0";
  }
  return "";
}

}  // namespace

OptimizationSummary OptimizePoseGraph(PoseGraphProblem* problem, const PoseGraphOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  OptimizationSummary out;
  out.message = options.Validate();
  if (out.message.empty()) out.message = ValidateGraph(*problem);
  if (!out.message.empty()) return out;
  if (problem->edges.empty()) {
    out.message = "no edges";
    return out;
  }
  std::vector<Sim3Block> blocks;
  bool any_fixed = false;
  for (const Sim3Node& n : problem->nodes) {
    blocks.push_back(PackSim3(n.world_from_cam));
    any_fixed = any_fixed || n.fixed;
  }
  std::unique_ptr<ceres::Manifold> manifold(NewSim3Manifold());
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem cp(po);
  std::vector<bool> added(blocks.size(), false);
  for (const Sim3Edge& e : problem->edges) {
    cp.AddResidualBlock(Sim3EdgeError::Create(e.i_from_j, e.weight), nullptr, blocks[e.i].data(), blocks[e.j].data());
    for (int n : {e.i, e.j}) {
      if (added[n]) continue;
      added[n] = true;
      cp.SetManifold(blocks[n].data(), manifold.get());
      const bool gauge = !any_fixed && options.fix_first_node_if_none_fixed && n == 0;
      if (problem->nodes[n].fixed || gauge) cp.SetParameterBlockConstant(blocks[n].data());
    }
  }
  if (!any_fixed && options.fix_first_node_if_none_fixed && !added[0]) {
    out.message = "node 0 (gauge) has no edge; fix a node explicitly";
    return out;
  }
  ceres::Solver::Options so;
  so.logging_type = ceres::SILENT;  // failed steps are handled; no log line per step
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.sparse_linear_algebra_library_type =
      ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ? ceres::SUITE_SPARSE
                                                                            : ceres::EIGEN_SPARSE;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = options.num_threads;
  so.function_tolerance = options.function_tolerance;
  so.initial_trust_region_radius = options.initial_trust_region_radius;
  ceres::Solver::Summary s;
  ceres::Solve(so, &cp, &s);
  out.usable = s.IsSolutionUsable();
  out.initial_cost = s.initial_cost;
  out.final_cost = s.final_cost;
  out.iterations = std::max(0, static_cast<int>(s.iterations.size()) - 1);
  out.message = s.BriefReport();
  if (out.usable) {
    for (size_t n = 0; n < blocks.size(); ++n) {
      if (!problem->nodes[n].fixed) problem->nodes[n].world_from_cam = UnpackSim3(blocks[n]);
    }
  }
  out.solve_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

int CorrectPointsByReference(const std::vector<SE3>& world_from_cam_before, const PoseGraphProblem& optimized,
                             const std::vector<int>& reference_node, std::vector<Eigen::Vector3d>* points_w) {
  const int num_nodes = static_cast<int>(optimized.nodes.size());
  if (static_cast<int>(world_from_cam_before.size()) != num_nodes || reference_node.size() != points_w->size()) {
    return 0;
  }
  int moved = 0;
  for (size_t k = 0; k < points_w->size(); ++k) {
    const int n = reference_node[k];
    if (n < 0 || n >= num_nodes) continue;
    (*points_w)[k] = CorrectPoint(world_from_cam_before[n], optimized.nodes[n].world_from_cam, (*points_w)[k]);
    ++moved;
  }
  return moved;
}

}  // namespace ccm::opt
