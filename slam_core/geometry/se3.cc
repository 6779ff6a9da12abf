#include "slam_core/geometry/se3.h"

#include <cmath>

#include "slam_core/geometry/so3_util.h"

namespace ccm {
namespace {

// Below this rotation angle the closed forms lose precision; Taylor series are exact to
// double precision there (error ~ theta^4).
constexpr double kSmallAngle = 1e-5;

// Left Jacobian V of SO(3): t = V * rho.
Eigen::Matrix3d LeftJacobian(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = internal::Hat(phi);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

Eigen::Matrix3d LeftJacobianInverse(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = internal::Hat(phi);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 12.0;
  const double half = 0.5 * theta;
  const double coef = (1.0 - half * std::cos(half) / std::sin(half)) / (theta * theta);
  return Eigen::Matrix3d::Identity() - 0.5 * W + coef * W * W;
}

Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  if (theta < kSmallAngle) {
    // First-order quaternion, renormalised by the constructor of SE3.
    return Eigen::Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  }
  return Eigen::Quaterniond(Eigen::AngleAxisd(theta, phi / theta));
}

Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // shortest rotation, angle in [0, pi]
  const double vn = q.vec().norm();
  if (vn < 1e-12) return 2.0 * q.vec();
  const double theta = 2.0 * std::atan2(vn, q.w());
  return theta / vn * q.vec();
}

}  // namespace

SE3 SE3::Exp(const Eigen::Matrix<double, 6, 1>& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  return SE3(ExpSO3(phi), LeftJacobian(phi) * rho);
}

Eigen::Matrix<double, 6, 1> SE3::Log() const {
  Eigen::Matrix<double, 6, 1> xi;
  const Eigen::Vector3d phi = LogSO3(q_);
  xi.head<3>() = LeftJacobianInverse(phi) * t_;
  xi.tail<3>() = phi;
  return xi;
}

SE3 SE3::Interpolate(const SE3& a, const SE3& b, double alpha) {
  return a * SE3::Exp(alpha * (a.inverse() * b).Log());
}

Eigen::Matrix4d SE3::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = q_.toRotationMatrix();
  m.topRightCorner<3, 1>() = t_;
  return m;
}

namespace internal {
Eigen::Quaterniond ExpSO3Public(const Eigen::Vector3d& phi) { return ExpSO3(phi); }
Eigen::Vector3d LogSO3Public(const Eigen::Quaterniond& q) { return LogSO3(q); }
}  // namespace internal

}  // namespace ccm
