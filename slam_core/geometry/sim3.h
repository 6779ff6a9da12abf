// Similarity transform b_from_a = (s, R, t): p_b = s * R * p_a + t.
// Monocular maps have arbitrary scale, so inter-map alignment (fusion, loop closure,
// trajectory evaluation) is a Sim(3), not an SE(3).
#pragma once

#include "slam_core/geometry/se3.h"

namespace ccm {

class Sim3 {
 public:
  Sim3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()), s_(1.0) {}
  Sim3(double scale, const Eigen::Quaterniond& q, const Eigen::Vector3d& t)
      : q_(q.normalized()), t_(t), s_(scale) {}
  explicit Sim3(const SE3& T) : q_(T.rotation()), t_(T.translation()), s_(1.0) {}

  static Sim3 Identity() { return Sim3(); }
  /// exp of [rho, phi, sigma] with sigma = log(scale).
  static Sim3 Exp(const Eigen::Matrix<double, 7, 1>& xi);
  Eigen::Matrix<double, 7, 1> Log() const;

  double scale() const { return s_; }
  const Eigen::Quaterniond& rotation() const { return q_; }
  Eigen::Matrix3d rotation_matrix() const { return q_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return t_; }
  Eigen::Matrix4d matrix() const;

  Sim3 inverse() const {
    const Eigen::Quaterniond qi = q_.conjugate();
    return Sim3(1.0 / s_, qi, -(qi * t_) / s_);
  }
  Sim3 operator*(const Sim3& o) const { return Sim3(s_ * o.s_, q_ * o.q_, s_ * (q_ * o.t_) + t_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return s_ * (q_ * p) + t_; }
  /// Applies this similarity to a camera pose world_from_cam (keeps the pose rigid:
  /// rotation composed, position mapped).
  SE3 TransformPose(const SE3& a_from_cam) const {
    return SE3(q_ * a_from_cam.rotation(), (*this) * a_from_cam.translation());
  }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
  double s_;
};

}  // namespace ccm
