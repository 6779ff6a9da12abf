// Pose-only optimization (declared in bundle_adjustment.h).
#include <algorithm>
#include <chrono>
#include <memory>

#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Cholesky>

#include "slam_core/optimization/bundle_adjustment.h"

namespace ccm::opt {
namespace {

// One round of pose-only Levenberg-Marquardt on the 6-dof tangent of the SE(3) block, with
// the same parameterization as NewSe3Manifold() (left quaternion increment, delta = phi / 2;
// additive translation) and the same whitened residual as PoseOnlyCostAnalytic. A 6x6
// system per iteration needs no sparse machinery: Ceres' per-solve set-up (problem,
// program, evaluator) cost more than the solve itself and was ~25 % of tracking time.
struct PosePassResult {
  bool usable = false;
  double initial_cost = 0.0, final_cost = 0.0;  ///< 0.5 * sum rho(|r|^2), Ceres' convention
  int iterations = 0;                           ///< accepted steps
  std::string message;
};

// Huber rho(s) on the squared residual s (Ceres' HuberLoss) and its IRLS weight rho'(s).
double HuberRho(double s, double delta) { return s <= delta * delta ? s : 2.0 * delta * std::sqrt(s) - delta * delta; }
double HuberWeight(double s, double delta) { return s <= delta * delta ? 1.0 : delta / std::sqrt(s); }

class PosePass {
 public:
  PosePass(const CameraModel& camera, const std::vector<PointObservation>& obs, const std::vector<bool>& active,
           bool robust, double huber_delta)
      : camera_(camera), obs_(obs), active_(active), robust_(robust), delta_(huber_delta) {}

  /// Cost at the pose; infinity when an active point cannot be projected (a step that
  /// carries a point behind the camera is rejected, as Ceres does on a failed evaluation).
  double Cost(const SE3& cam_from_world) const {
    double cost = 0.0;
    for (size_t i = 0; i < obs_.size(); ++i) {
      if (!active_[i]) continue;
      Eigen::Vector2d uv;
      if (!camera_.Project(cam_from_world * obs_[i].point_w, &uv)) return std::numeric_limits<double>::infinity();
      const double s = (uv - obs_[i].uv_px).squaredNorm() / (obs_[i].sigma_px * obs_[i].sigma_px);
      cost += robust_ ? HuberRho(s, delta_) : s;
    }
    return 0.5 * cost;
  }

  /// Gauss-Newton system (IRLS-weighted when robust) at the pose: H dx = -g.
  bool Linearize(const SE3& cam_from_world, Eigen::Matrix<double, 6, 6>* H, Eigen::Matrix<double, 6, 1>* g) const {
    H->setZero();
    g->setZero();
    const Eigen::Matrix3d R = cam_from_world.rotation().toRotationMatrix();
    for (size_t i = 0; i < obs_.size(); ++i) {
      if (!active_[i]) continue;
      const Eigen::Vector3d rotated = R * obs_[i].point_w;
      Eigen::Vector2d uv;
      Eigen::Matrix<double, 2, 3> J;
      if (!camera_.Project(rotated + cam_from_world.translation(), &uv, &J)) return false;
      const double inv_sigma = 1.0 / obs_[i].sigma_px;
      const Eigen::Vector2d r = (uv - obs_[i].uv_px) * inv_sigma;
      J *= inv_sigma;
      // Left perturbation R' = exp(phi) R with phi = 2 delta (Ceres' quaternion tangent):
      // d p_cam / d delta = -2 [R X]x (reprojection_cost_analytic.h derives the same).
      Eigen::Matrix3d minus_hat;
      minus_hat << 0, rotated.z(), -rotated.y(), -rotated.z(), 0, rotated.x(), rotated.y(), -rotated.x(), 0;
      Eigen::Matrix<double, 2, 6> Jt;
      Jt.leftCols<3>() = 2.0 * J * minus_hat;
      Jt.rightCols<3>() = J;
      const double w = robust_ ? HuberWeight(r.squaredNorm(), delta_) : 1.0;
      H->noalias() += w * Jt.transpose() * Jt;
      g->noalias() += w * Jt.transpose() * r;
    }
    return true;
  }

  static SE3 Plus(const SE3& T, const Eigen::Matrix<double, 6, 1>& dx) {
    const Eigen::Vector3d d = dx.head<3>();
    const double n = d.norm();
    Eigen::Quaterniond dq;
    if (n > 1e-12) {
      dq = Eigen::Quaterniond(std::cos(n), 0, 0, 0);
      dq.vec() = std::sin(n) / n * d;
    } else {
      dq = Eigen::Quaterniond(1.0, d.x(), d.y(), d.z());
    }
    Eigen::Quaterniond q = dq * T.rotation();
    q.normalize();
    return SE3(q, T.translation() + dx.tail<3>());
  }

  PosePassResult Run(int max_iterations, SE3* cam_from_world) const {
    PosePassResult out;
    double cost = Cost(*cam_from_world);
    out.initial_cost = out.final_cost = cost;
    if (!std::isfinite(cost)) {
      out.message = "initial cost not finite";
      return out;
    }
    out.usable = true;
    // Ceres' defaults: trust region 1e4 (damping 1e-4 on the Jacobian-scaled diagonal),
    // halved on a rejected step, function tolerance 1e-6, gradient tolerance 1e-10.
    double mu = 1e-4, nu = 2.0;
    Eigen::Matrix<double, 6, 6> H;
    Eigen::Matrix<double, 6, 1> g;
    bool relinearize = true;
    for (int it = 0; it < max_iterations; ++it) {
      if (relinearize && !Linearize(*cam_from_world, &H, &g)) break;
      relinearize = false;
      if (g.lpNorm<Eigen::Infinity>() <= 1e-10) break;
      Eigen::Matrix<double, 6, 6> A = H;
      for (int k = 0; k < 6; ++k) A(k, k) += mu * std::clamp(H(k, k), 1e-6, 1e32);
      const Eigen::Matrix<double, 6, 1> dx = A.ldlt().solve(-g);
      if (!dx.allFinite()) break;
      const SE3 candidate = Plus(*cam_from_world, dx);
      const double new_cost = Cost(candidate);
      if (new_cost < cost) {
        const double decrease = (cost - new_cost) / cost;
        *cam_from_world = candidate;
        cost = new_cost;
        ++out.iterations;
        relinearize = true;
        mu = std::max(mu / 3.0, 1e-16);
        nu = 2.0;
        if (decrease <= 1e-6) break;
      } else {
        mu *= nu;
        nu *= 2.0;
        if (mu > 1e16) break;
      }
    }
    out.final_cost = cost;
    out.message = "LM pose: cost " + std::to_string(out.initial_cost) + " -> " + std::to_string(cost) + ", " +
                  std::to_string(out.iterations) + " steps";
    return out;
  }

 private:
  const CameraModel& camera_;
  const std::vector<PointObservation>& obs_;
  const std::vector<bool>& active_;
  bool robust_;
  double delta_;
};

// chi2 of every observation at the pose; unprojectable ones are outliers.
int Classify(const CameraModel& camera, const std::vector<PointObservation>& obs, const SE3& cam_from_world,
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

}  // namespace

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
  SE3 pose = world_from_cam->inverse();
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
    const PosePassResult s =
        PosePass(camera, observations, active, robust, options.huber_delta).Run(options.iterations_per_round, &pose);
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
    num_active = Classify(camera, observations, pose, options.chi2_threshold, &active);
    // Classification converged: further robust rounds would repeat this one exactly, so go
    // straight to the final (non-robust) round. Saves up to two solves per tracked frame.
    if (active == before && round + 2 < options.num_rounds) round = options.num_rounds - 2;
  }
  out.inlier = active;
  out.num_inliers = num_active;
  out.usable = ok && num_active >= options.min_inliers;
  if (out.usable) {
    *world_from_cam = pose.inverse();
  } else if (out.message.empty() || ok) {
    out.message = "too few inliers: " + std::to_string(num_active);
  }
  out.solve_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace ccm::opt
