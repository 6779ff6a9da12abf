// Pieces shared by the optimizers' own Levenberg-Marquardt loops (pose_optimizer.cc,
// dense_schur_bundle.cc), which mirror Ceres' trust-region LM so that they reach the same
// minimum as the Ceres solves they replace. Internal to ccm_optimization.
#pragma once

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ccm::opt::internal {

// Ceres' defaults for a trust-region LM solve (those the callers do not set).
constexpr double kGradientTolerance = 1e-10, kParameterTolerance = 1e-8, kMinRelativeDecrease = 1e-3;
// Ceres' clamp of the LM damping diagonal.
constexpr double kMinDiagonal = 1e-6, kMaxDiagonal = 1e32;

/// Adds one whitened residual's rho(s) (s = squared norm; Huber of width `huber`, or s itself
/// when huber is 0) to *rho_sum and returns its Gauss-Newton weight rho'(s), which is what
/// Ceres' robust-loss correction reduces to for Huber.
inline double AddHuber(double s, double huber, double* rho_sum) {
  if (huber > 0.0 && s > huber * huber) {
    const double root = std::sqrt(s);
    *rho_sum += 2.0 * huber * root - huber * huber;
    return huber / root;
  }
  *rho_sum += s;
  return 1.0;
}

/// Jacobian of a whitened residual with respect to the pose's tangent (left rotation increment
/// phi, R' = exp(phi) R, then translation), given J = d(residual)/d(p_cam) and rotated = R X:
/// d(p_cam)/d(phi) = -[R X]x, d(p_cam)/d(t) = I.
inline Eigen::Matrix<double, 2, 6> PoseTangentJacobian(const Eigen::Matrix<double, 2, 3>& J,
                                                       const Eigen::Vector3d& rotated) {
  Eigen::Matrix<double, 2, 6> Jx;
  Jx.leftCols<3>() << J(0, 2) * rotated.y() - J(0, 1) * rotated.z(), J(0, 0) * rotated.z() - J(0, 2) * rotated.x(),
      J(0, 1) * rotated.x() - J(0, 0) * rotated.y(), J(1, 2) * rotated.y() - J(1, 1) * rotated.z(),
      J(1, 0) * rotated.z() - J(1, 2) * rotated.x(), J(1, 1) * rotated.x() - J(1, 0) * rotated.y();
  Jx.rightCols<3>() = J;
  return Jx;
}

/// exp(phi) * q, normalized.
inline Eigen::Quaterniond RotateLeft(const Eigen::Quaterniond& q, const Eigen::Vector3d& phi) {
  const double angle = phi.norm();
  const Eigen::Quaterniond dq =
      angle > 1e-12 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle))
                    : Eigen::Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  return (dq * q).normalized();
}

/// A matrix's LM damping: mu times its diagonal, clamped like Ceres'.
template <typename M>
auto DampingOf(const M& h, double mu) {
  return (mu * h.diagonal().cwiseMax(kMinDiagonal).cwiseMin(kMaxDiagonal)).eval();
}

/// Nielsen's trust-region rule (Ceres' LM): after a step of gain ratio rho, the next mu
/// (1 / radius) and its growth factor nu. Returns whether the step is taken.
inline bool UpdateDamping(double rho, double* mu, double* nu) {
  if (rho < kMinRelativeDecrease) {
    *mu *= *nu;
    *nu *= 2.0;
    return false;
  }
  *mu *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
  *nu = 2.0;
  return true;
}

}  // namespace ccm::opt::internal
