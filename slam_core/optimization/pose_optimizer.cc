// Pose-only optimization (declared in bundle_adjustment.h): ORB-SLAM's rounds of robust
// passes with reclassification, each pass a small Levenberg-Marquardt of its own.
#include <algorithm>
#include <chrono>
#include <memory>

#include <cmath>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/optimization/lm_building_blocks.h"
#include "slam_core/optimization/pose_manifold.h"

namespace ccm::opt {
namespace {

// One pass of Levenberg-Marquardt over the 6-dof pose, written out instead of a
// ceres::Problem: tracking runs two pose optimizations of up to four passes per frame, and
// building, preprocessing and tearing down a Problem of a few hundred residuals cost more
// than the 6x6 solves themselves (docs/deployment.md "Footprint by thread"). Same residual
// and Jacobian as PoseOnlyCostAnalytic, same cost convention as Ceres (1/2 sum rho(s), Huber
// rho with Ceres' first-order correction, i.e. weight rho'(s)), same trust-region update
// (Nielsen's rule, Ceres' defaults) and the same stopping tolerances.
struct PassResult {
  bool usable = false;
  double initial_cost = 0.0, final_cost = 0.0;
  int iterations = 0;
  std::string message;
};

struct PoseState {
  Eigen::Quaterniond q;  // cam_from_world
  Eigen::Vector3d t;
};

// The pass's cost at `x`, and with `h`/`g` its Gauss-Newton system in the tangent
// (left rotation increment, then translation). False when a point cannot be projected.
bool Linearize(const CameraModel& camera, const std::vector<PointObservation>& obs, const std::vector<bool>& active,
               double huber, const PoseState& x, double* cost, Eigen::Matrix<double, 6, 6>* h,
               Eigen::Matrix<double, 6, 1>* g) {
  const Eigen::Matrix3d R = x.q.toRotationMatrix();
  double total = 0.0;
  if (h) h->setZero(), g->setZero();
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> J;
  for (size_t i = 0; i < obs.size(); ++i) {
    if (!active[i]) continue;
    const Eigen::Vector3d rotated = R * obs[i].point_w;
    if (!camera.ProjectForCost(rotated + x.t, &uv, h ? &J : nullptr)) return false;
    const double inv_sigma = 1.0 / obs[i].sigma_px;
    const Eigen::Vector2d r = (uv - obs[i].uv_px) * inv_sigma;
    const double w = internal::AddHuber(r.squaredNorm(), huber, &total);
    if (!h) continue;
    J *= inv_sigma;
    const Eigen::Matrix<double, 2, 6> Jx = internal::PoseTangentJacobian(J, rotated);
    h->noalias() += w * Jx.transpose() * Jx;
    g->noalias() += w * Jx.transpose() * r;
  }
  *cost = 0.5 * total;
  return true;
}

PoseState Plus(const PoseState& x, const Eigen::Matrix<double, 6, 1>& dx) {
  return {internal::RotateLeft(x.q, dx.head<3>()), x.t + dx.tail<3>()};
}

PassResult RunPosePass(const CameraModel& camera, const std::vector<PointObservation>& obs,
                       const std::vector<bool>& active, bool robust, const PoseOptimizerOptions& options,
                       Se3Block* cam_from_world) {
  using internal::kGradientTolerance, internal::kParameterTolerance;
  constexpr double kFunctionTolerance = 1e-6;  // Ceres' default
  PassResult out;
  const double huber = robust ? options.huber_delta : 0.0;
  PoseState x{Eigen::Quaterniond((*cam_from_world)[3], (*cam_from_world)[0], (*cam_from_world)[1],
                                 (*cam_from_world)[2]).normalized(),
              Eigen::Vector3d((*cam_from_world)[4], (*cam_from_world)[5], (*cam_from_world)[6])};
  double cost = 0.0;
  Eigen::Matrix<double, 6, 6> h;
  Eigen::Matrix<double, 6, 1> g;
  if (!Linearize(camera, obs, active, huber, x, &cost, &h, &g) || !std::isfinite(cost)) {
    out.message = "pose pass: a point does not project at the initial pose";
    return out;
  }
  out.initial_cost = cost;
  double mu = 1e-4, nu = 2.0;  // 1 / Ceres' initial trust-region radius
  out.message = "no convergence within " + std::to_string(options.iterations_per_round) + " iterations";
  for (int it = 0; it < options.iterations_per_round; ++it) {
    ++out.iterations;
    if (g.lpNorm<Eigen::Infinity>() <= kGradientTolerance) {
      out.message = "gradient tolerance reached";
      break;
    }
    Eigen::Matrix<double, 6, 6> a = h;
    a.diagonal() += internal::DampingOf(h, mu);
    const Eigen::Matrix<double, 6, 1> dx = a.ldlt().solve(-g);
    if (!dx.allFinite()) {
      out.message = "pose pass: the linear solve failed";
      break;
    }
    const double x_norm = std::sqrt(x.q.coeffs().squaredNorm() + x.t.squaredNorm());
    if (dx.norm() <= kParameterTolerance * (x_norm + kParameterTolerance)) {
      out.message = "parameter tolerance reached";
      break;
    }
    const PoseState candidate = Plus(x, dx);
    // Linearized at the candidate at once: most steps are taken, so this saves a pass.
    double new_cost = 0.0;
    Eigen::Matrix<double, 6, 6> h_new;
    Eigen::Matrix<double, 6, 1> g_new;
    const bool evaluated = Linearize(camera, obs, active, huber, candidate, &new_cost, &h_new, &g_new) &&
                           std::isfinite(new_cost);
    const double model_decrease = -(g.dot(dx) + 0.5 * dx.dot(h * dx));
    const double rho = evaluated && model_decrease > 0.0 ? (cost - new_cost) / model_decrease : -1.0;
    // A worse step (or a point behind the camera) shrinks the trust region.
    if (!internal::UpdateDamping(rho, &mu, &nu)) continue;
    const double decrease = cost - new_cost;
    x = candidate;
    cost = new_cost;
    h = h_new;
    g = g_new;
    if (decrease <= kFunctionTolerance * (cost + decrease)) {
      out.message = "function tolerance reached";
      break;
    }
  }
  out.final_cost = cost;
  out.usable = true;
  *cam_from_world = {x.q.x(), x.q.y(), x.q.z(), x.q.w(), x.t.x(), x.t.y(), x.t.z()};
  return out;
}

// chi2 of every observation at the pose; unprojectable ones are outliers.
}  // namespace

int ClassifyObservations(const CameraModel& camera, const std::vector<PointObservation>& obs, const SE3& cam_from_world,
             double chi2_threshold, std::vector<bool>* inlier) {
  int n = 0;
  for (size_t i = 0; i < obs.size(); ++i) {
    Eigen::Vector2d uv;
    const bool ok = camera.Project(cam_from_world * obs[i].point_w, &uv) &&
                    (uv - obs[i].uv_px).squaredNorm() <= chi2_threshold * obs[i].sigma_px * obs[i].sigma_px;
    (*inlier)[i] = ok;
    n += ok ? 1 : 0;
  }
  return n;
}

std::string PoseOptimizerOptions::Validate() const {
  if (num_rounds < 1 || iterations_per_round < 1) return "num_rounds and iterations_per_round must be >= 1";
  if (!(chi2_threshold > 0.0)) return "chi2_threshold must be > 0";
  if (!(huber_delta > 0.0)) return "huber_delta must be > 0";
  if (min_inliers < 3) return "min_inliers must be >= 3 (a pose has 6 dof)";
  return "";
}

OptimizationSummary OptimizePose(const CameraModel& camera, const std::vector<PointObservation>& observations,
                                 SE3* world_from_cam, const PoseOptimizerOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  OptimizationSummary out;
  out.message = options.Validate();
  if (!out.message.empty()) return out;
  Se3Block pose = PackSe3(world_from_cam->inverse());
  // Like ORB-SLAM, every observation starts as an inlier (unless it cannot be projected).
  std::vector<bool> active(observations.size(), false);
  for (size_t i = 0; i < observations.size(); ++i) {
    Eigen::Vector2d uv;
    active[i] = camera.Project(world_from_cam->inverse() * observations[i].point_w, &uv);
  }
  int num_active = static_cast<int>(std::count(active.begin(), active.end(), true));
  bool ok = true;
  for (int round = 0; round < options.num_rounds && num_active >= options.min_inliers; ++round) {
    const bool robust = round + 1 < options.num_rounds;
    const PassResult s = RunPosePass(camera, observations, active, robust, options, &pose);
    if (!s.usable) {
      ok = false;
      out.message = s.message;
      break;
    }
    if (round == 0) out.initial_cost = s.initial_cost;
    out.final_cost = s.final_cost;
    out.iterations += s.iterations;
    out.message = s.message;
    const std::vector<bool> before = active;
    num_active = ClassifyObservations(camera, observations, UnpackSe3(pose), options.chi2_threshold, &active);
    // Classification converged: further robust rounds would repeat this one exactly, so go
    // straight to the final (non-robust) round. Saves up to two solves per tracked frame.
    if (active == before && round + 2 < options.num_rounds) round = options.num_rounds - 2;
  }
  out.inlier = active;
  out.num_inliers = num_active;
  out.usable = ok && num_active >= options.min_inliers;
  if (out.usable) {
    *world_from_cam = UnpackSe3(pose).inverse();
  } else if (out.message.empty() || ok) {
    out.message = "too few inliers: " + std::to_string(num_active);
  }
  out.solve_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace ccm::opt
