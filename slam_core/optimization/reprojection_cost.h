// Ceres reprojection cost functors (autodiff, templated on T, static Create()).
//
// Measurement model (why pixels through any CameraModel): residuals are distorted-pixel
// errors divided by the keypoint sigma, so the chi2 thresholds of ORB-SLAM apply exactly
// and any ccm::CameraModel (pinhole-radtan, fisheye, future models) works without a
// templated copy of its projection. The camera is a virtual double-precision function, so
// ProjectJet() pushes autodiff Jets through it with the chain rule, using the analytic
// 2x3 Jacobian the CameraModel already provides. Rigid-body parts stay autodiff.
//
// Pose parameter block: 7 doubles [qx qy qz qw tx ty tz] = cam_from_world (Eigen
// quaternion storage order), on the manifold from PoseManifold() (see pose_manifold.h).
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam_core/geometry/camera.h"

namespace ccm::opt {

/// Projects a camera-frame point through CameraModel::ProjectForCost (continued past the
/// distortion's fold); false only where the model has no pixel for it.
inline bool ProjectJet(const CameraModel& camera, const double* p_cam, double* uv) {
  Eigen::Vector2d out;
  if (!camera.ProjectForCost(Eigen::Vector3d(p_cam[0], p_cam[1], p_cam[2]), &out)) return false;
  uv[0] = out.x();
  uv[1] = out.y();
  return true;
}

/// Jet overload: value through the camera, derivatives by d(uv)/d(p) * d(p)/d(params).
template <int N>
bool ProjectJet(const CameraModel& camera, const ceres::Jet<double, N>* p_cam,
                ceres::Jet<double, N>* uv) {
  Eigen::Vector2d out;
  Eigen::Matrix<double, 2, 3> d_uv_d_p;
  if (!camera.ProjectForCost(Eigen::Vector3d(p_cam[0].a, p_cam[1].a, p_cam[2].a), &out, &d_uv_d_p)) {
    return false;
  }
  for (int r = 0; r < 2; ++r) {
    uv[r].a = out[r];
    uv[r].v = d_uv_d_p(r, 0) * p_cam[0].v + d_uv_d_p(r, 1) * p_cam[1].v + d_uv_d_p(r, 2) * p_cam[2].v;
  }
  return true;
}

/// (projection of p_cam - z) / sigma; false where ProjectJet is.
template <typename T>
bool WhitenedResidual(const CameraModel& camera, const T* p_cam, const Eigen::Vector2d& z, double inv_sigma, T* residual) {
  T uv[2];
  if (!ProjectJet(camera, p_cam, uv)) return false;
  residual[0] = (uv[0] - z.x()) * inv_sigma;
  residual[1] = (uv[1] - z.y()) * inv_sigma;
  return true;
}

/// Rotates and translates a world point into the camera: p_c = q * p_w + t.
template <typename T, typename P>
void TransformToCamera(const T* cam_from_world, const P* point_w, T* p_cam) {
  const Eigen::Map<const Eigen::Quaternion<T>> q(cam_from_world);
  const Eigen::Matrix<T, 3, 1> p{T(point_w[0]), T(point_w[1]), T(point_w[2])};
  const Eigen::Matrix<T, 3, 1> pc = q * p;
  for (int i = 0; i < 3; ++i) p_cam[i] = pc[i] + cam_from_world[4 + i];
}

/// Pose + point reprojection error (bundle adjustment). Residual: (uv - z) / sigma.
class ReprojectionError {
 public:
  ReprojectionError(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera_(camera), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* cam_from_world, const T* point_w, T* residual) const {
    T p_cam[3];
    TransformToCamera(cam_from_world, point_w, p_cam);
    return WhitenedResidual(*camera_, p_cam, uv_, inv_sigma_, residual);
  }

  /// The camera must outlive the cost function (the Ceres problem).
  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector2d& uv_px,
                                     double sigma_px) {
    return new ceres::AutoDiffCostFunction<ReprojectionError, 2, 7, 3>(
        new ReprojectionError(camera, uv_px, sigma_px));
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

/// Reprojection error of a point in inverse-depth coordinates of an anchor camera, for points of
/// low parallax: block [a b rho] is the point rho^-1 * (a, b, 1) in the anchor. Parameters:
/// anchor cam_from_world, observer cam_from_world, [a b rho]. The observer sees rho * p_obs =
/// R_o R_a^T ((a, b, 1) - rho t_a) + rho t_o, which projects like p_obs for rho > 0 and stays
/// finite at rho -> 0 (a point at infinity), where an XYZ point slides through a camera.
class InverseDepthReprojectionError {
 public:
  InverseDepthReprojectionError(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera_(camera), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* anchor_from_world, const T* cam_from_world, const T* abr, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(anchor_from_world);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_a(anchor_from_world + 4);
    const Eigen::Map<const Eigen::Quaternion<T>> q_o(cam_from_world);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_o(cam_from_world + 4);
    const Eigen::Matrix<T, 3, 1> ray(abr[0], abr[1], T(1.0));
    const Eigen::Matrix<T, 3, 1> h_w = q_a.conjugate() * (ray - t_a * abr[2]);
    const Eigen::Matrix<T, 3, 1> h_o = q_o * h_w + t_o * abr[2];
    const T p_cam[3] = {h_o[0], h_o[1], h_o[2]};
    return WhitenedResidual(*camera_, p_cam, uv_, inv_sigma_, residual);
  }

  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction<InverseDepthReprojectionError, 2, 7, 7, 3>(
        new InverseDepthReprojectionError(camera, uv_px, sigma_px));
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

/// The anchor's own view of an inverse-depth point: the ray (a, b, 1), whatever the depth.
class AnchorRayReprojectionError {
 public:
  AnchorRayReprojectionError(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera_(camera), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* abr, T* residual) const {
    const T p_cam[3] = {abr[0], abr[1], T(1.0)};
    return WhitenedResidual(*camera_, p_cam, uv_, inv_sigma_, residual);
  }

  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction<AnchorRayReprojectionError, 2, 3>(
        new AnchorRayReprojectionError(camera, uv_px, sigma_px));
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

/// Pose-only reprojection error: the 3D point is a constant (tracking, relocalisation).
class PoseOnlyReprojectionError {
 public:
  PoseOnlyReprojectionError(const CameraModel* camera, const Eigen::Vector3d& point_w,
                            const Eigen::Vector2d& uv_px, double sigma_px)
      : camera_(camera), point_w_(point_w), uv_(uv_px), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* cam_from_world, T* residual) const {
    T p_cam[3];
    TransformToCamera(cam_from_world, point_w_.data(), p_cam);
    return WhitenedResidual(*camera_, p_cam, uv_, inv_sigma_, residual);
  }

  static ceres::CostFunction* Create(const CameraModel* camera, const Eigen::Vector3d& point_w,
                                     const Eigen::Vector2d& uv_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction<PoseOnlyReprojectionError, 2, 7>(
        new PoseOnlyReprojectionError(camera, point_w, uv_px, sigma_px));
  }

 private:
  const CameraModel* camera_;
  Eigen::Vector3d point_w_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

}  // namespace ccm::opt
