// Analytic-Jacobian twin of ReprojectionError for the hot path of bundle adjustment
// (global BA evaluates ~10^5-10^6 residuals per iteration; autodiff Jets cost ~4x more).
// Same residual, same 7-double cam_from_world block on NewSe3Manifold(). The pose Jacobian
// is returned in ambient (quaternion) coordinates such that J_ambient * PlusJacobian equals
// the exact tangent Jacobian; optimization_test checks it against the autodiff functor.
#pragma once

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam_core/geometry/camera.h"

namespace ccm::opt {

class ReprojectionCostAnalytic final : public ceres::SizedCostFunction<2, 7, 3> {
 public:
  /// The camera must outlive the cost function.
  ReprojectionCostAnalytic(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera_(camera), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px) {
    return new ReprojectionCostAnalytic(camera, uv_px, sigma_px);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t(parameters[0] + 4);
    const Eigen::Map<const Eigen::Vector3d> point_w(parameters[1]);
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const Eigen::Vector3d rotated = R * point_w;
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 3> J;  // d(whitened uv) / d(p_cam)
    if (!camera_->Project(rotated + t, &uv, jacobians ? &J : nullptr)) return false;
    residuals[0] = (uv.x() - uv_.x()) * inv_sigma_;
    residuals[1] = (uv.y() - uv_.y()) * inv_sigma_;
    if (!jacobians) return true;
    J *= inv_sigma_;
    if (jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, 2, 7, Eigen::RowMajor>> jp(jacobians[0]);
      // Left perturbation R' = exp(phi) R: d(p_cam)/d(phi) = -[R X]x.
      Eigen::Matrix3d minus_hat;
      minus_hat << 0, rotated.z(), -rotated.y(), -rotated.z(), 0, rotated.x(), rotated.y(), -rotated.x(), 0;
      const Eigen::Matrix<double, 2, 3> j_phi = J * minus_hat;
      // Ceres' quaternion tangent is delta = phi / 2 and PlusJacobian P (4x3, rows x y z w)
      // has orthonormal columns, so J_q = 2 * J_phi * P^T gives J_q * P = d r / d delta.
      const double x = q.x(), y = q.y(), z = q.z(), w = q.w();
      Eigen::Matrix<double, 4, 3> P;
      P << w, z, -y, -z, w, x, y, -x, w, -x, -y, -z;
      jp.leftCols<4>() = 2.0 * j_phi * P.transpose();
      jp.rightCols<3>() = J;
    }
    if (jacobians[1]) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jx(jacobians[1]);
      jx = J * R;
    }
    return true;
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

}  // namespace ccm::opt
