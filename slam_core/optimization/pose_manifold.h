// Parameter-block layouts and Ceres manifolds for poses, plus packing helpers.
// SE(3) block: 7 doubles [qx qy qz qw tx ty tz] (Eigen quaternion order), manifold =
// EigenQuaternion x R^3 (6-dof tangent). Sim(3) block: 8 doubles [qx qy qz qw tx ty tz
// log_s], manifold = EigenQuaternion x R^4 (7-dof tangent); log-scale keeps s > 0 and
// makes a scale error of x% cost the same at any absolute scale.
#pragma once

#include <array>
#include <cmath>

#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include "slam_core/geometry/se3.h"
#include "slam_core/geometry/sim3.h"

namespace ccm::opt {

using Se3Block = std::array<double, 7>;
using Sim3Block = std::array<double, 8>;

/// New manifold for a 7-double SE(3) block; the ceres::Problem takes ownership.
inline ceres::Manifold* NewSe3Manifold() {
  return new ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>();
}

/// SE(3) block whose translation component `axis` (0..2) is held constant (scale gauge).
inline ceres::Manifold* NewSe3ManifoldWithFixedTranslationAxis(int axis) {
  return new ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::SubsetManifold>(
      ceres::EigenQuaternionManifold(), ceres::SubsetManifold(3, {axis}));
}

/// New manifold for an 8-double Sim(3) block; the ceres::Problem takes ownership.
inline ceres::Manifold* NewSim3Manifold() {
  return new ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<4>>();
}

inline Se3Block PackSe3(const SE3& T) {
  const Eigen::Quaterniond& q = T.rotation();
  const Eigen::Vector3d& t = T.translation();
  return {q.x(), q.y(), q.z(), q.w(), t.x(), t.y(), t.z()};
}

inline SE3 UnpackSe3(const Se3Block& b) {
  return SE3(Eigen::Quaterniond(b[3], b[0], b[1], b[2]), Eigen::Vector3d(b[4], b[5], b[6]));
}

inline Sim3Block PackSim3(const Sim3& S) {
  const Eigen::Quaterniond& q = S.rotation();
  const Eigen::Vector3d& t = S.translation();
  return {q.x(), q.y(), q.z(), q.w(), t.x(), t.y(), t.z(), std::log(S.scale())};
}

inline Sim3 UnpackSim3(const Sim3Block& b) {
  return Sim3(std::exp(b[7]), Eigen::Quaterniond(b[3], b[0], b[1], b[2]),
              Eigen::Vector3d(b[4], b[5], b[6]));
}

}  // namespace ccm::opt
