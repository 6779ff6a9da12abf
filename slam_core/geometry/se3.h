// Rigid transform b_from_a: maps points expressed in frame a into frame b.
// Naming convention in the whole code base: `world_from_cam` (T_w_c), `cam_from_world`.
// Stored as unit quaternion + translation; composition and inverse are exact.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ccm {

class SE3 {
 public:
  SE3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  SE3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(q.normalized()), t_(t) {}
  SE3(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) : q_(Eigen::Quaterniond(R).normalized()), t_(t) {}

  static SE3 Identity() { return SE3(); }
  /// exp of a twist xi = [rho (translation part), phi (rotation vector)].
  static SE3 Exp(const Eigen::Matrix<double, 6, 1>& xi);
  /// log: inverse of Exp, returns [rho, phi].
  Eigen::Matrix<double, 6, 1> Log() const;
  /// Geodesic interpolation: alpha = 0 -> a, alpha = 1 -> b.
  static SE3 Interpolate(const SE3& a, const SE3& b, double alpha);

  const Eigen::Quaterniond& rotation() const { return q_; }
  Eigen::Matrix3d rotation_matrix() const { return q_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return t_; }
  Eigen::Matrix4d matrix() const;

  SE3 inverse() const {
    const Eigen::Quaterniond qi = q_.conjugate();
    return SE3(qi, -(qi * t_));
  }
  SE3 operator*(const SE3& o) const { return SE3(q_ * o.q_, q_ * o.t_ + t_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

}  // namespace ccm
