#include "slam_core/optimization/dense_schur_bundle.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "slam_core/optimization/lm_building_blocks.h"

namespace ccm::opt::internal {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat63 = Eigen::Matrix<double, 6, 3>;

constexpr double kMaxMu = 1e32;  // 1 / Ceres' smallest trust-region radius

// Which poses and points are unknowns, and each free point's observations.
struct Layout {
  std::vector<int> obs;         // active observation indices into problem.observations
  std::vector<int> free_pose;   // problem pose -> unknown index, -1 if fixed or unobserved
  std::vector<int> free_point;  // problem point -> unknown index, -1 if fixed or unobserved
  int num_free_poses = 0, num_free_points = 0;
  std::vector<int> point_begin, point_obs;  // CSR: positions in `obs` of each free point's observations
};

Layout MakeLayout(const BundleProblem& problem, const std::vector<bool>& active, const std::vector<bool>& pose_fixed) {
  Layout l;
  l.free_pose.assign(problem.poses.size(), -1);
  l.free_point.assign(problem.points.size(), -1);
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    if (!active[i]) continue;
    const Observation& o = problem.observations[i];
    l.obs.push_back(static_cast<int>(i));
    if (!pose_fixed[o.pose_index] && l.free_pose[o.pose_index] < 0) l.free_pose[o.pose_index] = l.num_free_poses++;
    if (!problem.points[o.point_index].fixed && l.free_point[o.point_index] < 0) {
      l.free_point[o.point_index] = l.num_free_points++;
    }
  }
  std::vector<int> count(l.num_free_points + 1, 0);
  for (const int i : l.obs) {
    const int x = l.free_point[problem.observations[i].point_index];
    if (x >= 0) ++count[x + 1];
  }
  for (int x = 0; x < l.num_free_points; ++x) count[x + 1] += count[x];
  l.point_begin = count;
  l.point_obs.resize(count.back());
  for (size_t k = 0; k < l.obs.size(); ++k) {
    const int x = l.free_point[problem.observations[l.obs[k]].point_index];
    if (x >= 0) l.point_obs[count[x]++] = static_cast<int>(k);
  }
  return l;
}

// Gauss-Newton blocks in the tangent: pose (left rotation increment, then translation) and
// point; W per observation (pose-point coupling, only where both are free).
struct Linearization {
  double cost = 0.0;
  std::vector<Mat6> U;
  std::vector<Vec6> gu;
  std::vector<Eigen::Matrix3d> V;
  std::vector<Eigen::Vector3d> gv;
  std::vector<Mat63> W;
};

struct State {
  std::vector<Se3Block> poses;
  std::vector<Eigen::Vector3d> points;
};

// Cost (Ceres' convention, 1/2 sum rho) and its blocks. False when an observation cannot be
// evaluated (a point behind a pinhole camera).
bool Linearize(const BundleProblem& problem, const Layout& l, const BundlePassOptions& options,
               const BundlePassVariables& v, const State& x, Linearization* lin) {
  std::vector<Eigen::Matrix3d> R(problem.poses.size());
  std::vector<bool> have_r(problem.poses.size(), false);
  lin->U.assign(l.num_free_poses, Mat6::Zero());
  lin->gu.assign(l.num_free_poses, Vec6::Zero());
  lin->V.assign(l.num_free_points, Eigen::Matrix3d::Zero());
  lin->gv.assign(l.num_free_points, Eigen::Vector3d::Zero());
  lin->W.resize(l.obs.size());
  double total = 0.0;
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> J;
  Eigen::Matrix<double, 2, 6> Jp;
  for (size_t k = 0; k < l.obs.size(); ++k) {
    const Observation& o = problem.observations[l.obs[k]];
    const Se3Block& b = x.poses[o.pose_index];
    if (!have_r[o.pose_index]) {
      R[o.pose_index] = Eigen::Quaterniond(b[3], b[0], b[1], b[2]).toRotationMatrix();
      have_r[o.pose_index] = true;
    }
    const Eigen::Vector3d rotated = R[o.pose_index] * x.points[o.point_index];
    const CameraModel& camera = *problem.cameras[problem.poses[o.pose_index].camera_index];
    if (!camera.ProjectForCost(rotated + Eigen::Vector3d(b[4], b[5], b[6]), &uv, &J)) return false;
    const double inv_sigma = 1.0 / o.sigma_px;
    const Eigen::Vector2d r = (uv - o.uv_px) * inv_sigma;
    const double w = AddHuber(r.squaredNorm(), options.huber_delta, &total);
    J *= inv_sigma;
    const int p = l.free_pose[o.pose_index], m = l.free_point[o.point_index];
    if (p >= 0) {
      Jp = PoseTangentJacobian(J, rotated);
      if (o.pose_index == v.scale_gauge_pose) Jp.col(3 + v.scale_gauge_axis).setZero();
      lin->U[p].noalias() += w * Jp.transpose() * Jp;
      lin->gu[p].noalias() += w * Jp.transpose() * r;
    }
    if (m >= 0) {
      const Eigen::Matrix<double, 2, 3> Jx = J * R[o.pose_index];
      lin->V[m].noalias() += w * Jx.transpose() * Jx;
      lin->gv[m].noalias() += w * Jx.transpose() * r;
      if (p >= 0) lin->W[k].noalias() = w * Jp.transpose() * Jx;
    }
  }
  lin->cost = 0.5 * total;
  return std::isfinite(total);
}

// Ceres' Jacobi scaling: each variable's column scaled by 1 / (1 + sqrt(diag(J'J))), so the
// reduced system stays well conditioned when some points sit close to a camera (Jacobians
// of 1e6) and others far away (1e-3); unscaled, its solve lost the step and every step of
// such a BA was rejected.
template <int N>
Eigen::Matrix<double, N, 1> JacobiScale(const Eigen::Matrix<double, N, N>& h) {
  return (1.0 + h.diagonal().array().sqrt()).inverse().matrix();
}

// Solves the damped system by eliminating the points (Schur complement on the poses) and
// back-substituting them, in Jacobi-scaled variables like Ceres (the LM damping, mu times
// the clamped diagonal, is taken of the scaled system). Returns false if the reduced system
// cannot be solved. `model_decrease`: the linear model's predicted cost decrease.
bool SolveStep(const BundleProblem& problem, const Layout& l, const BundlePassVariables& v, const Linearization& lin,
               double mu, std::vector<Vec6>* dpose, std::vector<Eigen::Vector3d>* dpoint, double* model_decrease) {
  const int n = l.num_free_poses;
  std::vector<Vec6> su(n);
  std::vector<Eigen::Vector3d> sv(l.num_free_points);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(6 * n, 6 * n);
  Eigen::VectorXd b(6 * n);
  std::vector<Vec6> damp_u(n);
  double decrease = 0.0;  // -g.d + d' D d in scaled variables, halved at the end (exact solve)
  for (int p = 0; p < n; ++p) {
    su[p] = JacobiScale<6>(lin.U[p]);
    const Mat6 u = su[p].asDiagonal() * lin.U[p] * su[p].asDiagonal();
    damp_u[p] = DampingOf(u, mu);
    S.block<6, 6>(6 * p, 6 * p) = u;
    S.block<6, 6>(6 * p, 6 * p).diagonal() += damp_u[p];
    b.segment<6>(6 * p) = -su[p].cwiseProduct(lin.gu[p]);
  }
  std::vector<Eigen::Matrix3d> v_inv(l.num_free_points);
  std::vector<Eigen::Vector3d> damp_v(l.num_free_points);
  std::vector<Mat63> ws(l.obs.size());  // scaled W
  for (int m = 0; m < l.num_free_points; ++m) {
    sv[m] = JacobiScale<3>(lin.V[m]);
    Eigen::Matrix3d vd = sv[m].asDiagonal() * lin.V[m] * sv[m].asDiagonal();
    damp_v[m] = DampingOf(vd, mu);
    vd.diagonal() += damp_v[m];
    v_inv[m] = vd.inverse();
    if (!v_inv[m].allFinite()) return false;
    const Eigen::Vector3d gv = sv[m].cwiseProduct(lin.gv[m]);
    for (int a = l.point_begin[m]; a < l.point_begin[m + 1]; ++a) {
      const int ka = l.point_obs[a];
      const int pa = l.free_pose[problem.observations[l.obs[ka]].pose_index];
      if (pa >= 0) ws[ka].noalias() = su[pa].asDiagonal() * lin.W[ka] * sv[m].asDiagonal();
    }
    for (int a = l.point_begin[m]; a < l.point_begin[m + 1]; ++a) {
      const int ka = l.point_obs[a];
      const int pa = l.free_pose[problem.observations[l.obs[ka]].pose_index];
      if (pa < 0) continue;
      const Mat63 wv = ws[ka] * v_inv[m];
      b.segment<6>(6 * pa).noalias() += wv * gv;
      for (int c = a; c < l.point_begin[m + 1]; ++c) {
        const int kc = l.point_obs[c];
        const int pc = l.free_pose[problem.observations[l.obs[kc]].pose_index];
        if (pc < 0) continue;
        const Mat6 block = wv * ws[kc].transpose();
        S.block<6, 6>(6 * pa, 6 * pc) -= block;
        if (c != a) S.block<6, 6>(6 * pc, 6 * pa) -= block.transpose();
      }
    }
  }
  int gauge_row = -1;
  if (v.scale_gauge_pose >= 0 && l.free_pose[v.scale_gauge_pose] >= 0) {
    // The held translation component: decoupled by its zero Jacobian column; its step is 0.
    gauge_row = 6 * l.free_pose[v.scale_gauge_pose] + 3 + v.scale_gauge_axis;
    S.row(gauge_row).setZero();
    S.col(gauge_row).setZero();
    S(gauge_row, gauge_row) = 1.0;
    b(gauge_row) = 0.0;
  }
  Eigen::VectorXd d = Eigen::VectorXd::Zero(6 * n);
  if (n > 0) {
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
    if (ldlt.info() != Eigen::Success) return false;
    d = ldlt.solve(b);
    if (!d.allFinite()) return false;
  }
  if (gauge_row >= 0) d(gauge_row) = 0.0;
  dpose->resize(n);
  for (int p = 0; p < n; ++p) {
    const Vec6 dp = d.segment<6>(6 * p);  // scaled
    decrease += -(su[p].cwiseProduct(lin.gu[p])).dot(dp) + dp.dot(damp_u[p].cwiseProduct(dp));
    (*dpose)[p] = su[p].cwiseProduct(dp);
  }
  dpoint->resize(l.num_free_points);
  for (int m = 0; m < l.num_free_points; ++m) {
    const Eigen::Vector3d gv = sv[m].cwiseProduct(lin.gv[m]);
    Eigen::Vector3d rhs = -gv;
    for (int a = l.point_begin[m]; a < l.point_begin[m + 1]; ++a) {
      const int ka = l.point_obs[a];
      const int pa = l.free_pose[problem.observations[l.obs[ka]].pose_index];
      if (pa >= 0) rhs.noalias() -= ws[ka].transpose() * d.segment<6>(6 * pa);
    }
    const Eigen::Vector3d dx = v_inv[m] * rhs;  // scaled
    if (!dx.allFinite()) return false;
    decrease += -gv.dot(dx) + dx.dot(damp_v[m].cwiseProduct(dx));
    (*dpoint)[m] = sv[m].cwiseProduct(dx);
  }
  *model_decrease = 0.5 * decrease;
  return true;
}

State Plus(const BundleProblem& problem, const Layout& l, const State& x, const std::vector<Vec6>& dpose,
           const std::vector<Eigen::Vector3d>& dpoint) {
  State out = x;
  for (size_t i = 0; i < problem.poses.size(); ++i) {
    const int p = l.free_pose[i];
    if (p < 0) continue;
    const Se3Block& b = x.poses[i];
    const Eigen::Quaterniond q = RotateLeft(Eigen::Quaterniond(b[3], b[0], b[1], b[2]), dpose[p].head<3>());
    out.poses[i] = {q.x(), q.y(), q.z(), q.w(), b[4] + dpose[p][3], b[5] + dpose[p][4], b[6] + dpose[p][5]};
  }
  for (size_t i = 0; i < problem.points.size(); ++i) {
    if (l.free_point[i] >= 0) out.points[i] += dpoint[l.free_point[i]];
  }
  return out;
}

double MaxGradient(const Linearization& lin) {
  double g = 0.0;
  for (const Vec6& x : lin.gu) g = std::max(g, x.lpNorm<Eigen::Infinity>());
  for (const Eigen::Vector3d& x : lin.gv) g = std::max(g, x.lpNorm<Eigen::Infinity>());
  return g;
}

double StepAndStateNorms(const Layout& l, const State& x, const std::vector<Vec6>& dpose,
                         const std::vector<Eigen::Vector3d>& dpoint, double* step_norm) {
  double s = 0.0, n = 0.0;
  for (const Vec6& d : dpose) s += d.squaredNorm();
  for (const Eigen::Vector3d& d : dpoint) s += d.squaredNorm();
  for (size_t i = 0; i < x.poses.size(); ++i) {
    if (l.free_pose[i] < 0) continue;
    for (const double c : x.poses[i]) n += c * c;
  }
  for (size_t i = 0; i < x.points.size(); ++i) {
    if (l.free_point[i] >= 0) n += x.points[i].squaredNorm();
  }
  *step_norm = std::sqrt(s);
  return std::sqrt(n);
}

}  // namespace

int CountFreePoses(const BundleProblem& problem, const std::vector<bool>& active, const std::vector<bool>& pose_fixed) {
  std::vector<bool> seen(problem.poses.size(), false);
  int n = 0;
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    const int p = problem.observations[i].pose_index;
    if (!active[i] || pose_fixed[p] || seen[p]) continue;
    seen[p] = true;
    ++n;
  }
  return n;
}

BundlePassResult RunDenseSchurPass(const BundleProblem& problem, const std::vector<bool>& active,
                                   const BundlePassOptions& options, const BundlePassVariables& v) {
  BundlePassResult out;
  const Layout l = MakeLayout(problem, active, *v.pose_fixed);
  State x{*v.cam_from_world, *v.points_w};
  Linearization lin;
  if (!Linearize(problem, l, options, v, x, &lin)) {
    out.message = "bundle pass: an observation cannot be evaluated at the initial point";
    return out;
  }
  out.usable = true;
  out.initial_cost = lin.cost;
  double mu = 1.0 / options.initial_trust_region_radius, nu = 2.0;
  out.message = "no convergence within " + std::to_string(options.max_iterations) + " iterations";
  std::vector<Vec6> dpose;
  std::vector<Eigen::Vector3d> dpoint;
  Linearization next;
  for (int it = 0; it < options.max_iterations; ++it) {
    if (options.abort && options.abort->load()) {
      out.message = "aborted";
      break;
    }
    if (MaxGradient(lin) <= kGradientTolerance) {
      out.message = "gradient tolerance reached";
      break;
    }
    ++out.iterations;
    double model_decrease = 0.0;
    bool step_ok = SolveStep(problem, l, v, lin, mu, &dpose, &dpoint, &model_decrease);
    if (step_ok) {
      double step_norm = 0.0;
      const double x_norm = StepAndStateNorms(l, x, dpose, dpoint, &step_norm);
      if (step_norm <= kParameterTolerance * (x_norm + kParameterTolerance)) {
        out.message = "parameter tolerance reached";
        break;
      }
    }
    State candidate;
    if (step_ok) {
      candidate = Plus(problem, l, x, dpose, dpoint);
      step_ok = Linearize(problem, l, options, v, candidate, &next);
    }
    const double rho = step_ok && model_decrease > 0.0 ? (lin.cost - next.cost) / model_decrease : -1.0;
    if (!UpdateDamping(rho, &mu, &nu)) {  // a worse step, a failed solve or a point behind a camera
      ++out.unsuccessful_steps;
      if (mu > kMaxMu) {
        out.message = "trust region too small";
        break;
      }
      continue;
    }
    const double decrease = lin.cost - next.cost;
    x = std::move(candidate);
    std::swap(lin, next);
    if (decrease <= options.function_tolerance * (lin.cost + decrease)) {
      out.message = "function tolerance reached";
      break;
    }
  }
  out.final_cost = lin.cost;
  *v.cam_from_world = std::move(x.poses);
  *v.points_w = std::move(x.points);
  return out;
}

}  // namespace ccm::opt::internal
