// Analytic-Jacobian twins of ReprojectionError / PoseOnlyReprojectionError, used by the
// optimizers (global BA evaluates ~10^5-10^6 residuals per iteration; autodiff Jets cost
// several times more). Same residual, same 7-double cam_from_world block on NewSe3Manifold(). The pose Jacobian
// is returned in ambient (quaternion) coordinates such that J_ambient * PlusJacobian equals
// the exact tangent Jacobian; optimization_test checks it against the autodiff functor.
#pragma once

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam_core/geometry/camera.h"

namespace ccm::opt {

namespace internal {

/// Whitened reprojection residual of point_w in pose cam_from_world (7 doubles) with
/// optional row-major Jacobians: jac_pose 2x7 (ambient, see file comment), jac_point 2x3.
inline bool EvaluateReprojection(const CameraModel& camera, const Eigen::Vector2d& z, double inv_sigma,
                                 const double* cam_from_world, const double* point_w, double* residuals,
                                 double* jac_pose, double* jac_point) {
  const Eigen::Map<const Eigen::Quaterniond> q(cam_from_world);
  const Eigen::Map<const Eigen::Vector3d> t(cam_from_world + 4);
  const Eigen::Matrix3d R = q.toRotationMatrix();
  const Eigen::Vector3d rotated = R * Eigen::Map<const Eigen::Vector3d>(point_w);
  const bool want_jacobians = jac_pose || jac_point;
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> J;  // d(whitened uv) / d(p_cam)
  if (!camera.ProjectForCost(rotated + t, &uv, want_jacobians ? &J : nullptr)) return false;
  residuals[0] = (uv.x() - z.x()) * inv_sigma;
  residuals[1] = (uv.y() - z.y()) * inv_sigma;
  if (!want_jacobians) return true;
  J *= inv_sigma;
  if (jac_pose) {
    Eigen::Map<Eigen::Matrix<double, 2, 7, Eigen::RowMajor>> jp(jac_pose);
    // Left perturbation R' = exp(phi) R: d(p_cam)/d(phi) = -[R X]x.
    Eigen::Matrix3d minus_hat;
    minus_hat << 0, rotated.z(), -rotated.y(), -rotated.z(), 0, rotated.x(), rotated.y(), -rotated.x(), 0;
    const Eigen::Matrix<double, 2, 3> j_phi = J * minus_hat;
    // Ceres' quaternion tangent is delta = phi / 2 and PlusJacobian P (4x3, rows x y z w)
    // has orthonormal columns, so J_q = 2 * J_phi * P^T gives J_q * P = d r / d delta.
    const double x = q.x(), y = q.y(), zq = q.z(), w = q.w();
    Eigen::Matrix<double, 4, 3> P;
    P << w, zq, -y, -zq, w, x, y, -x, w, -x, -y, -zq;
    jp.leftCols<4>() = 2.0 * j_phi * P.transpose();
    jp.rightCols<3>() = J;
  }
  if (jac_point) {
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jx(jac_point);
    jx = J * R;
  }
  return true;
}

}  // namespace internal

/// Pose + point (bundle adjustment).
class ReprojectionCostAnalytic final : public ceres::SizedCostFunction<2, 7, 3> {
 public:
  /// The camera must outlive the cost function.
  ReprojectionCostAnalytic(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera_(camera), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px) {
    return new ReprojectionCostAnalytic(camera, uv_px, sigma_px);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return internal::EvaluateReprojection(*camera_, uv_, inv_sigma_, parameters[0], parameters[1], residuals,
                                          jacobians ? jacobians[0] : nullptr, jacobians ? jacobians[1] : nullptr);
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

/// Pose only, the point is a constant (tracking).
class PoseOnlyCostAnalytic final : public ceres::SizedCostFunction<2, 7> {
 public:
  PoseOnlyCostAnalytic(const CameraModel* camera, const Eigen::Vector3d& point_w, const Eigen::Vector2d& uv_px,
                       double sigma_px)
      : camera_(camera), point_w_(point_w), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector3d& point_w,
                                     const Eigen::Vector2d& uv_px, double sigma_px) {
    return new PoseOnlyCostAnalytic(camera, point_w, uv_px, sigma_px);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return internal::EvaluateReprojection(*camera_, uv_, inv_sigma_, parameters[0], point_w_.data(), residuals,
                                          jacobians ? jacobians[0] : nullptr, nullptr);
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector3d point_w_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

}  // namespace ccm::opt
