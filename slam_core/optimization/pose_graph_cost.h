// Ceres functor of a Sim(3) pose-graph edge (autodiff, templated on T, static Create()).
// Blocks: two 8-double Sim(3) world_from_cam blocks [qx qy qz qw tx ty tz log_s].
#pragma once

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam_core/geometry/sim3.h"

namespace ccm::opt {

/// Residual [t, rotation vector, log s] of E = measured_i_from_j^-1 * S_wi^-1 * S_wj.
class Sim3EdgeError {
 public:
  Sim3EdgeError(const Sim3& i_from_j, double weight)
      : meas_inv_(i_from_j.inverse()), log_s_meas_inv_(std::log(meas_inv_.scale())), sqrt_w_(std::sqrt(weight)) {}

  template <typename T>
  bool operator()(const T* world_from_i, const T* world_from_j, T* residual) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> qi(world_from_i);
    const Eigen::Map<const Eigen::Quaternion<T>> qj(world_from_j);
    const Eigen::Map<const Vec3> ti(world_from_i + 4);
    const Eigen::Map<const Vec3> tj(world_from_j + 4);
    // rel = S_wi^-1 * S_wj = (s_j / s_i, qi^-1 qj, qi^-1 (tj - ti) / s_i)
    const Eigen::Quaternion<T> qi_inv = qi.conjugate();
    const Eigen::Quaternion<T> q_rel = qi_inv * qj;
    const Vec3 t_rel = (qi_inv * (tj - ti)) * exp(-world_from_i[7]);
    const T log_s_rel = world_from_j[7] - world_from_i[7];
    // E = M^-1 * rel
    const Eigen::Quaternion<T> qm = meas_inv_.rotation().cast<T>();
    const Eigen::Quaternion<T> q_e = qm * q_rel;
    const Vec3 t_e = T(meas_inv_.scale()) * (qm * t_rel) + meas_inv_.translation().cast<T>();
    const T q_wxyz[4] = {q_e.w(), q_e.x(), q_e.y(), q_e.z()};
    T rotvec[3];
    ceres::QuaternionToAngleAxis(q_wxyz, rotvec);
    for (int k = 0; k < 3; ++k) {
      residual[k] = T(sqrt_w_) * t_e[k];
      residual[3 + k] = T(sqrt_w_) * rotvec[k];
    }
    residual[6] = T(sqrt_w_) * (log_s_rel + T(log_s_meas_inv_));
    return true;
  }

  static ceres::CostFunction* Create(const Sim3& i_from_j, double weight) {
    return new ceres::AutoDiffCostFunction<Sim3EdgeError, 7, 8, 8>(new Sim3EdgeError(i_from_j, weight));
  }

 private:
  Sim3 meas_inv_;
  double log_s_meas_inv_;
  double sqrt_w_;
};

}  // namespace ccm::opt
