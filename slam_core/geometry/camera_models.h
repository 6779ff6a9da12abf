// Concrete camera models behind the CameraModel interface. Use MakeCamera() unless a
// test needs the concrete type.
#pragma once

#include "slam_core/geometry/camera.h"

namespace ccm {

/// Pinhole with radial-tangential (Brown-Conrady, OpenCV/EuRoC "radtan") distortion
/// k1 k2 p1 p2 [k3]. Points are valid where the distortion map is locally invertible,
/// so Project never returns a folded-over pixel.
class PinholeRadTanCamera final : public CameraModel {
 public:
  explicit PinholeRadTanCamera(const CameraIntrinsics& intrinsics);
  CameraType type() const override { return CameraType::kPinholeRadTan; }
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  bool Project(const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv,
               Eigen::Matrix<double, 2, 3>* d_uv_d_p = nullptr) const override;
  bool ProjectForCost(const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv,
                      Eigen::Matrix<double, 2, 3>* d_uv_d_p = nullptr) const override;
  bool Unproject(const Eigen::Vector2d& uv, Eigen::Vector3d* bearing) const override;

 private:
  bool ProjectChecked(const Eigen::Vector3d& p_cam, bool check_fold, Eigen::Vector2d* uv,
                      Eigen::Matrix<double, 2, 3>* d_uv_d_p) const;
  /// Distorts normalized coordinates; optional 2x2 Jacobian d(distorted)/d(xy).
  Eigen::Vector2d Distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* jac) const;

  CameraIntrinsics intrinsics_;
  double k1_ = 0, k2_ = 0, p1_ = 0, p2_ = 0, k3_ = 0;
};

/// Equidistant fisheye (Kannala-Brandt, OpenCV fisheye / EuRoC "equidistant"):
/// theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8).
/// Valid for incidence angles up to max_theta_rad (where theta_d is still increasing).
class FisheyeEquidistantCamera final : public CameraModel {
 public:
  explicit FisheyeEquidistantCamera(const CameraIntrinsics& intrinsics);
  CameraType type() const override { return CameraType::kFisheyeEquidistant; }
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  bool Project(const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv,
               Eigen::Matrix<double, 2, 3>* d_uv_d_p = nullptr) const override;
  bool ProjectForCost(const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv,
                      Eigen::Matrix<double, 2, 3>* d_uv_d_p = nullptr) const override;
  bool Unproject(const Eigen::Vector2d& uv, Eigen::Vector3d* bearing) const override;
  double max_theta_rad() const { return max_theta_rad_; }

 private:
  bool ProjectUpTo(const Eigen::Vector3d& p_cam, double max_theta_rad, Eigen::Vector2d* uv,
                   Eigen::Matrix<double, 2, 3>* d_uv_d_p) const;
  double ThetaD(double theta, double* d_theta_d = nullptr) const;

  CameraIntrinsics intrinsics_;
  double k_[4] = {0, 0, 0, 0};
  double max_theta_rad_ = 0;
};

}  // namespace ccm
