// Small SO(3) helpers shared by the SE3/Sim3 implementations (not part of the public API).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ccm::internal {

inline Eigen::Matrix3d Hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return m;
}

}  // namespace ccm::internal

namespace ccm::internal {
/// exp/log of SO(3) with rotation vectors (defined in se3.cc).
Eigen::Quaterniond ExpSO3Public(const Eigen::Vector3d& phi);
Eigen::Vector3d LogSO3Public(const Eigen::Quaterniond& q);
}  // namespace ccm::internal
