#include "slam_core/optimization/bundle_adjustment.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "slam_core/common/stopwatch.h"
#include "slam_core/optimization/dense_schur_bundle.h"
#include "slam_core/optimization/pose_manifold.h"
#include "slam_core/optimization/reprojection_cost.h"
#include "slam_core/optimization/reprojection_cost_analytic.h"

namespace ccm::opt {
namespace {

// An anchored point's inverse depth stays at or above this (1 km at map scale ~1 m): a step
// may push a far point to infinity, not past it.
constexpr double kMinInverseDepth = 1e-3;

ceres::LinearSolverType ToCeres(BaLinearSolver solver, int num_free_poses) {
  switch (solver) {
    case BaLinearSolver::kIterativeSchur: return ceres::ITERATIVE_SCHUR;
    case BaLinearSolver::kDenseSchur: return ceres::DENSE_SCHUR;
    case BaLinearSolver::kSparseSchur: return ceres::SPARSE_SCHUR;
    case BaLinearSolver::kAuto: break;
  }
  return num_free_poses <= kDenseSchurMaxFreePoses ? ceres::DENSE_SCHUR : ceres::SPARSE_SCHUR;
}

ceres::Problem::Options ProblemOptionsNotOwning() {
  // Manifold and loss are shared by many blocks and owned by the caller's unique_ptrs.
  // Indices were validated (ValidateProblem), so Ceres' per-residual checks are skipped.
  ceres::Problem::Options options;
  options.disable_all_safety_checks = true;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}

// Working copy of a BundleProblem's variables so a failed solve leaves the input untouched.
struct BundleVariables {
  std::vector<Se3Block> cam_from_world;
  std::vector<Eigen::Vector3d> points_w;
  // Points with an anchor (PointBlock::anchor_pose, usable: in front of it): [a b rho], the
  // point rho^-1 (a, b, 1) in the anchor camera; points_w follows them after every pass.
  std::vector<int> anchor;
  std::vector<Eigen::Vector3d> inverse_depth;
  std::vector<bool> pose_fixed;
  int scale_gauge_pose = -1;  ///< pose whose translation component scale_gauge_axis is held
  int scale_gauge_axis = 0;
};

// Puts the anchored points back into world coordinates after a pass moved their anchors or depths.
void UpdateAnchoredPoints(BundleVariables* v) {
  for (size_t i = 0; i < v->points_w.size(); ++i) {
    if (v->anchor[i] < 0) continue;
    const Eigen::Vector3d& abr = v->inverse_depth[i];
    const double rho = std::max(abr.z(), kMinInverseDepth);
    v->points_w[i] = UnpackSe3(v->cam_from_world[v->anchor[i]]).inverse() * (Eigen::Vector3d(abr.x(), abr.y(), 1.0) / rho);
  }
}

BundleVariables CopyVariables(const BundleProblem& problem) {
  BundleVariables v;
  for (const PoseBlock& p : problem.poses) {
    v.cam_from_world.push_back(PackSe3(p.world_from_cam.inverse()));
    v.pose_fixed.push_back(p.fixed);
  }
  for (const PointBlock& p : problem.points) {
    v.points_w.push_back(p.position_w);
    int anchor = p.fixed ? -1 : p.anchor_pose;
    Eigen::Vector3d abr = Eigen::Vector3d::Zero();
    if (anchor >= 0) {
      const Eigen::Vector3d p_a = problem.poses[anchor].world_from_cam.inverse() * p.position_w;
      if (p_a.z() > 0.0 && std::isfinite(p_a.z())) {
        abr = Eigen::Vector3d(p_a.x() / p_a.z(), p_a.y() / p_a.z(), std::max(1.0 / p_a.z(), kMinInverseDepth));
      } else {
        anchor = -1;  // behind the anchor (a wide fisheye): stays a free 3D point
      }
    }
    v.anchor.push_back(anchor);
    v.inverse_depth.push_back(abr);
  }
  UpdateAnchoredPoints(&v);
  return v;
}

void WriteBack(const BundleVariables& v, BundleProblem* problem) {
  for (size_t i = 0; i < problem->poses.size(); ++i) {
    if (!problem->poses[i].fixed) problem->poses[i].world_from_cam = UnpackSe3(v.cam_from_world[i]).inverse();
  }
  for (size_t i = 0; i < problem->points.size(); ++i) {
    if (!problem->points[i].fixed) problem->points[i].position_w = v.points_w[i];
  }
}

// Fixes the first observed pose when no observed pose is fixed (6-dof gauge).
void FixGaugeIfNeeded(const BundleProblem& problem, const std::vector<bool>& active, BundleVariables* v) {
  int first_observed = -1;
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    if (!active[i]) continue;
    const int p = problem.observations[i].pose_index;
    if (v->pose_fixed[p]) return;
    if (first_observed < 0 || p < first_observed) first_observed = p;
  }
  if (first_observed >= 0) v->pose_fixed[first_observed] = true;
}

// Monocular scale gauge: with exactly one observed pose fixed, the map can still scale about
// that camera. Holding one translation component of the pose that moves most under such a
// scaling removes exactly that freedom (nothing else is constrained). A fixed point already
// fixes the scale, so then nothing is done.
void FixScaleGauge(const BundleProblem& problem, const std::vector<bool>& active, BundleVariables* v) {
  std::vector<bool> observed(problem.poses.size(), false);
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    if (!active[i]) continue;
    if (problem.points[problem.observations[i].point_index].fixed) return;
    observed[problem.observations[i].pose_index] = true;
  }
  int fixed = -1, num_fixed = 0;
  for (size_t p = 0; p < observed.size(); ++p) {
    if (!observed[p] || !v->pose_fixed[p]) continue;
    fixed = static_cast<int>(p);
    ++num_fixed;
  }
  if (num_fixed != 1) return;
  const Eigen::Vector3d fixed_centre = problem.poses[fixed].world_from_cam.translation();
  double best = 0.0;
  for (size_t p = 0; p < observed.size(); ++p) {
    if (!observed[p] || v->pose_fixed[p]) continue;
    // d(t_cam_from_world)/d(scale) = -R_cw (c - c_fixed)
    const Eigen::Vector3d d = UnpackSe3(v->cam_from_world[p]).rotation() *
                              (problem.poses[p].world_from_cam.translation() - fixed_centre);
    for (int k = 0; k < 3; ++k) {
      if (std::abs(d[k]) <= best) continue;
      best = std::abs(d[k]);
      v->scale_gauge_pose = static_cast<int>(p);
      v->scale_gauge_axis = k;
    }
  }
}

// Stops Ceres between iterations once the caller's abort flag is set.
class AbortCallback final : public ceres::IterationCallback {
 public:
  explicit AbortCallback(const std::atomic<bool>* flag) : flag_(flag) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return flag_->load() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::atomic<bool>* flag_;
};

// One Levenberg-Marquardt pass over the active observations, on Ceres.
internal::BundlePassResult RunCeresPass(const BundleProblem& problem, const std::vector<bool>& active,
                                     bool robust, int max_iterations,
                                     const BundleAdjusterOptions& options, BundleVariables* v) {
  std::unique_ptr<ceres::Manifold> manifold(NewSe3Manifold());
  std::unique_ptr<ceres::Manifold> gauge_manifold(NewSe3ManifoldWithFixedTranslationAxis(v->scale_gauge_axis));
  std::unique_ptr<ceres::LossFunction> huber(new ceres::HuberLoss(options.huber_delta));
  ceres::Problem cp(ProblemOptionsNotOwning());
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  std::vector<bool> pose_added(problem.poses.size(), false), point_added(problem.points.size(), false);
  bool any_free_point = false;
  int num_free_poses = 0;
  const auto add_pose = [&](int index) {
    if (pose_added[index]) return;
    pose_added[index] = true;
    double* pose = v->cam_from_world[index].data();
    cp.SetManifold(pose, index == v->scale_gauge_pose ? gauge_manifold.get() : manifold.get());
    if (v->pose_fixed[index]) cp.SetParameterBlockConstant(pose);
    num_free_poses += v->pose_fixed[index] ? 0 : 1;
    ordering->AddElementToGroup(pose, 1);
  };
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    if (!active[i]) continue;
    const Observation& o = problem.observations[i];
    const CameraModel* camera = problem.cameras[problem.poses[o.pose_index].camera_index].get();
    double* pose = v->cam_from_world[o.pose_index].data();
    ceres::LossFunction* loss = robust ? huber.get() : nullptr;
    const int anchor = v->anchor[o.point_index];
    double* point = anchor >= 0 ? v->inverse_depth[o.point_index].data() : v->points_w[o.point_index].data();
    if (anchor == o.pose_index) {
      cp.AddResidualBlock(AnchorRayReprojectionError::Create(camera, o.uv_px, o.sigma_px), loss, point);
    } else if (anchor >= 0) {
      cp.AddResidualBlock(InverseDepthReprojectionError::Create(camera, o.uv_px, o.sigma_px), loss,
                          v->cam_from_world[anchor].data(), pose, point);
      add_pose(anchor);
      add_pose(o.pose_index);
    } else {
      cp.AddResidualBlock(ReprojectionCostAnalytic::Create(camera, o.uv_px, o.sigma_px), loss, pose, point);
      add_pose(o.pose_index);
    }
    if (!point_added[o.point_index]) {
      point_added[o.point_index] = true;
      if (problem.points[o.point_index].fixed) cp.SetParameterBlockConstant(point);
      if (anchor >= 0) cp.SetParameterLowerBound(point, 2, kMinInverseDepth);
      any_free_point = any_free_point || !problem.points[o.point_index].fixed;
      ordering->AddElementToGroup(point, 0);
    }
  }
  ceres::Solver::Options so;
  so.logging_type = ceres::SILENT;  // failed steps are handled; no log line per step
  so.max_num_iterations = max_iterations;
  so.num_threads = options.num_threads;
  so.function_tolerance = options.function_tolerance;
  so.initial_trust_region_radius = options.initial_trust_region_radius;
  so.linear_solver_type = any_free_point ? ToCeres(options.linear_solver, num_free_poses) : ceres::DENSE_QR;
  if (any_free_point) so.linear_solver_ordering = ordering;
  if (options.linear_solver == BaLinearSolver::kIterativeSchur) so.preconditioner_type = ceres::SCHUR_JACOBI;
  so.sparse_linear_algebra_library_type =
      ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ? ceres::SUITE_SPARSE
                                                                            : ceres::EIGEN_SPARSE;
  AbortCallback abort(options.abort);
  if (options.abort) so.callbacks.push_back(&abort);
  ceres::Solver::Summary summary;
  if (cp.NumResidualBlocks() > 0) ceres::Solve(so, &cp, &summary);
  internal::BundlePassResult out;
  out.usable = summary.IsSolutionUsable();
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  out.unsuccessful_steps = summary.num_unsuccessful_steps;
  out.message = summary.BriefReport();
  return out;
}

// kAuto with free XYZ points only and a window of at most kDenseSchurMaxFreePoses free
// poses (every local BA): our own dense-Schur LM (dense_schur_bundle.h), else Ceres.
internal::BundlePassResult RunBundlePass(const BundleProblem& problem, const std::vector<bool>& active, bool robust,
                                         int max_iterations, const BundleAdjusterOptions& options,
                                         BundleVariables* v) {
  bool own = options.linear_solver == BaLinearSolver::kAuto;
  for (size_t i = 0; own && i < problem.observations.size(); ++i) {
    own = !active[i] || v->anchor[problem.observations[i].point_index] < 0;
  }
  own = own && internal::CountFreePoses(problem, active, v->pose_fixed) <= kDenseSchurMaxFreePoses;
  if (!own) return RunCeresPass(problem, active, robust, max_iterations, options, v);
  internal::BundlePassOptions po;
  po.huber_delta = robust ? options.huber_delta : 0.0;
  po.max_iterations = max_iterations;
  po.function_tolerance = options.function_tolerance;
  po.initial_trust_region_radius = options.initial_trust_region_radius;
  po.abort = options.abort;
  internal::BundlePassVariables vars{&v->cam_from_world, &v->points_w, &v->pose_fixed, v->scale_gauge_pose,
                                     v->scale_gauge_axis};
  return internal::RunDenseSchurPass(problem, active, po, vars);
}

// Marks observations whose chi2 (with the working variables) is within the threshold.
std::vector<bool> ClassifyObservations(const BundleProblem& problem, const BundleVariables& v,
                                       double chi2_threshold, int* num_inliers) {
  std::vector<SE3> cam_from_world;
  for (const Se3Block& b : v.cam_from_world) cam_from_world.push_back(UnpackSe3(b));
  std::vector<bool> inlier(problem.observations.size(), false);
  *num_inliers = 0;
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    const Observation& o = problem.observations[i];
    const CameraModel& camera = *problem.cameras[problem.poses[o.pose_index].camera_index];
    Eigen::Vector2d uv;
    if (!camera.Project(cam_from_world[o.pose_index] * v.points_w[o.point_index], &uv)) continue;
    inlier[i] = (uv - o.uv_px).squaredNorm() <= chi2_threshold * o.sigma_px * o.sigma_px;
    *num_inliers += inlier[i] ? 1 : 0;
  }
  return inlier;
}

}  // namespace

const char* BaLinearSolverName(BaLinearSolver solver) {
  switch (solver) {
    case BaLinearSolver::kAuto: return "auto";
    case BaLinearSolver::kSparseSchur: return "sparse";
    case BaLinearSolver::kIterativeSchur: return "iterative";
    case BaLinearSolver::kDenseSchur: return "dense";
  }
  return "?";
}

bool ParseBaLinearSolver(const std::string& name, BaLinearSolver* solver) {
  for (const BaLinearSolver s : {BaLinearSolver::kAuto, BaLinearSolver::kSparseSchur, BaLinearSolver::kIterativeSchur,
                                 BaLinearSolver::kDenseSchur}) {
    if (name == BaLinearSolverName(s)) {
      *solver = s;
      return true;
    }
  }
  return false;
}

std::string BundleAdjusterOptions::Validate() const {
  if (robust_iterations < 0 || refine_iterations < 0) return "iterations must be >= 0";
  if (robust_iterations + refine_iterations == 0) return "at least one iteration is needed";
  if (!(chi2_threshold > 0.0)) return "chi2_threshold must be > 0";
  if (!(huber_delta > 0.0)) return "huber_delta must be > 0";
  if (num_threads < 1) return "num_threads must be >= 1";
  if (!(function_tolerance > 0.0)) return "function_tolerance must be > 0";
  if (!(initial_trust_region_radius > 0.0)) return "initial_trust_region_radius must be > 0";
  return "";
}

BundleAdjusterOptions LocalBaDefaults() { return BundleAdjusterOptions{}; }

BundleAdjusterOptions GlobalBaDefaults() {
  BundleAdjusterOptions o;
  o.robust_iterations = 15;
  o.refine_iterations = 0;
  o.reject_outliers = false;
  o.num_threads = 2;
  return o;
}

OptimizationSummary BundleAdjust(BundleProblem* problem, const BundleAdjusterOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  OptimizationSummary out;
  out.message = ValidateProblem(*problem);
  if (out.message.empty()) out.message = options.Validate();
  if (!out.message.empty()) return out;

  BundleVariables v = CopyVariables(*problem);
  std::vector<bool> active(problem->observations.size());
  for (size_t i = 0; i < active.size(); ++i) active[i] = ObservationChi2(*problem, problem->observations[i]) >= 0.0;
  if (std::find(active.begin(), active.end(), true) == active.end()) {
    out.message = "no observation can be projected";
    return out;
  }
  if (options.fix_first_pose_if_none_fixed) FixGaugeIfNeeded(*problem, active, &v);
  if (options.fix_scale_if_one_pose_fixed) FixScaleGauge(*problem, active, &v);

  bool ok = true;
  bool first_pass = true;
  auto run = [&](bool robust, int iterations) {
    const internal::BundlePassResult s = RunBundlePass(*problem, active, robust, iterations, options, &v);
    UpdateAnchoredPoints(&v);
    ok = ok && s.usable;
    if (first_pass) out.initial_cost = s.initial_cost;
    first_pass = false;
    out.final_cost = s.final_cost;
    out.iterations += s.iterations;
    out.rejected_steps += s.unsuccessful_steps;
    out.message = s.message;
  };
  if (options.robust_iterations > 0) run(true, options.robust_iterations);
  if (ok && options.refine_iterations > 0) {
    if (options.reject_outliers) {
      int n = 0;
      active = ClassifyObservations(*problem, v, options.chi2_threshold, &n);
    }
    run(false, options.refine_iterations);
  }
  if (options.abort && options.abort->load()) {
    ok = false;
    out.message = "aborted";
  }
  out.usable = ok;
  if (ok) {
    out.inlier = ClassifyObservations(*problem, v, options.chi2_threshold, &out.num_inliers);
    WriteBack(v, problem);
  }
  out.solve_time_s = SecondsSince(start);
  return out;
}

}  // namespace ccm::opt
