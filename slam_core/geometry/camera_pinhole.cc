#include <cmath>

#include <Eigen/LU>

#include "slam_core/geometry/camera_models.h"

namespace ccm {
namespace {
constexpr int kMaxUndistortIterations = 30;
// Undistortion must reproduce the pixel to this accuracy (in normalized units; ~1e-9 px).
constexpr double kUndistortTolerance = 1e-12;
}  // namespace

PinholeRadTanCamera::PinholeRadTanCamera(const CameraIntrinsics& intrinsics)
    : intrinsics_(intrinsics) {
  const auto& d = intrinsics_.distortion;
  if (d.size() >= 4) {
    k1_ = d[0];
    k2_ = d[1];
    p1_ = d[2];
    p2_ = d[3];
  }
  if (d.size() >= 5) k3_ = d[4];
}

Eigen::Vector2d PinholeRadTanCamera::Distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* jac) const {
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
  const Eigen::Vector2d out(x * radial + 2.0 * p1_ * x * y + p2_ * (r2 + 2.0 * x * x),
                            y * radial + p1_ * (r2 + 2.0 * y * y) + 2.0 * p2_ * x * y);
  if (jac) {
    const double d_radial_d_r2 = k1_ + r2 * (2.0 * k2_ + 3.0 * r2 * k3_);
    (*jac)(0, 0) = radial + 2.0 * x * x * d_radial_d_r2 + 2.0 * p1_ * y + 6.0 * p2_ * x;
    (*jac)(0, 1) = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1_ * x + 2.0 * p2_ * y;
    (*jac)(1, 0) = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1_ * x + 2.0 * p2_ * y;
    (*jac)(1, 1) = radial + 2.0 * y * y * d_radial_d_r2 + 6.0 * p1_ * y + 2.0 * p2_ * x;
  }
  return out;
}

bool PinholeRadTanCamera::Project(const Eigen::Vector3d& p, Eigen::Vector2d* uv,
                                  Eigen::Matrix<double, 2, 3>* d_uv_d_p) const {
  return ProjectChecked(p, true, uv, d_uv_d_p);
}

bool PinholeRadTanCamera::ProjectForCost(const Eigen::Vector3d& p, Eigen::Vector2d* uv,
                                         Eigen::Matrix<double, 2, 3>* d_uv_d_p) const {
  return ProjectChecked(p, false, uv, d_uv_d_p);
}

bool PinholeRadTanCamera::ProjectChecked(const Eigen::Vector3d& p, bool check_fold, Eigen::Vector2d* uv,
                                         Eigen::Matrix<double, 2, 3>* d_uv_d_p) const {
  if (p.z() <= 1e-9) return false;
  const double iz = 1.0 / p.z();
  const Eigen::Vector2d xy(p.x() * iz, p.y() * iz);
  Eigen::Matrix2d jd;
  const Eigen::Vector2d d = Distort(xy, &jd);
  // Beyond the fold of the distortion polynomial the mapping is not one-to-one;
  // such points would appear at a wrong pixel, so they are not visible.
  if (check_fold && jd.determinant() <= 0.0) return false;
  *uv = Eigen::Vector2d(intrinsics_.fx * d.x() + intrinsics_.cx, intrinsics_.fy * d.y() + intrinsics_.cy);
  if (d_uv_d_p) {
    Eigen::Matrix<double, 2, 3> d_xy_d_p;
    d_xy_d_p << iz, 0, -p.x() * iz * iz, 0, iz, -p.y() * iz * iz;
    const Eigen::Matrix2d f = Eigen::Vector2d(intrinsics_.fx, intrinsics_.fy).asDiagonal();
    *d_uv_d_p = f * jd * d_xy_d_p;
  }
  return true;
}

bool PinholeRadTanCamera::Unproject(const Eigen::Vector2d& uv, Eigen::Vector3d* bearing) const {
  const Eigen::Vector2d target((uv.x() - intrinsics_.cx) / intrinsics_.fx,
                               (uv.y() - intrinsics_.cy) / intrinsics_.fy);
  Eigen::Vector2d xy = target;  // Gauss-Newton from the distorted point
  for (int i = 0; i < kMaxUndistortIterations; ++i) {
    Eigen::Matrix2d j;
    const Eigen::Vector2d r = Distort(xy, &j) - target;
    if (r.squaredNorm() < kUndistortTolerance * kUndistortTolerance) break;
    if (std::abs(j.determinant()) < 1e-12) return false;
    xy -= j.lu().solve(r);
  }
  Eigen::Matrix2d j;
  if ((Distort(xy, &j) - target).norm() > 1e-9 || j.determinant() <= 0.0) return false;
  *bearing = Eigen::Vector3d(xy.x(), xy.y(), 1.0).normalized();
  return true;
}

}  // namespace ccm
