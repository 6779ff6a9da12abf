#include <algorithm>
#include <cmath>

#include "slam_core/geometry/camera_models.h"

namespace ccm {
namespace {
constexpr double kPi = 3.14159265358979323846;
// Rays this close to the optical axis use the pinhole limit of the model (no 0/0).
constexpr double kAxisEpsilon = 1e-12;
}  // namespace

FisheyeEquidistantCamera::FisheyeEquidistantCamera(const CameraIntrinsics& intrinsics)
    : intrinsics_(intrinsics) {
  for (size_t i = 0; i < 4 && i < intrinsics_.distortion.size(); ++i) k_[i] = intrinsics_.distortion[i];
  // Largest angle (up to 110 deg off-axis) before theta_d stops increasing: beyond it
  // the model is not invertible.
  max_theta_rad_ = 110.0 * kPi / 180.0;
  for (double th = 0.0; th < max_theta_rad_; th += 1e-3) {
    double d = 0;
    ThetaD(th, &d);
    if (d <= 0.0) {
      max_theta_rad_ = th;
      break;
    }
  }
}

double FisheyeEquidistantCamera::ThetaD(double theta, double* d_theta_d) const {
  const double t2 = theta * theta;
  const double poly = 1.0 + t2 * (k_[0] + t2 * (k_[1] + t2 * (k_[2] + t2 * k_[3])));
  if (d_theta_d) *d_theta_d = 1.0 + t2 * (3 * k_[0] + t2 * (5 * k_[1] + t2 * (7 * k_[2] + t2 * 9 * k_[3])));
  return theta * poly;
}

bool FisheyeEquidistantCamera::Project(const Eigen::Vector3d& p, Eigen::Vector2d* uv,
                                       Eigen::Matrix<double, 2, 3>* d_uv_d_p) const {
  return ProjectUpTo(p, max_theta_rad_, uv, d_uv_d_p);
}

bool FisheyeEquidistantCamera::ProjectForCost(const Eigen::Vector3d& p, Eigen::Vector2d* uv,
                                              Eigen::Matrix<double, 2, 3>* d_uv_d_p) const {
  // Past max_theta the polynomial turns back but stays smooth; only the ray straight
  // backwards (r -> 0 with Z < 0) has no defined pixel.
  return ProjectUpTo(p, std::max(max_theta_rad_, kPi - 1e-3), uv, d_uv_d_p);
}

bool FisheyeEquidistantCamera::ProjectUpTo(const Eigen::Vector3d& p, double max_theta_rad, Eigen::Vector2d* uv,
                                           Eigen::Matrix<double, 2, 3>* d_uv_d_p) const {
  const double X = p.x(), Y = p.y(), Z = p.z();
  const double r2 = X * X + Y * Y;
  const double r = std::sqrt(r2);
  const double theta = std::atan2(r, Z);
  if (theta >= max_theta_rad || p.squaredNorm() < 1e-18) return false;
  const double fx = intrinsics_.fx, fy = intrinsics_.fy;
  if (r < kAxisEpsilon * std::abs(Z)) {
    // On the axis: theta_d / r -> 1 / Z, same first-order behaviour as a pinhole.
    *uv = Eigen::Vector2d(fx * X / Z + intrinsics_.cx, fy * Y / Z + intrinsics_.cy);
    if (d_uv_d_p) *d_uv_d_p << fx / Z, 0, -fx * X / (Z * Z), 0, fy / Z, -fy * Y / (Z * Z);
    return true;
  }
  double dtd = 0;
  const double td = ThetaD(theta, &dtd);
  const double g = td / r;  // distorted = g * (X, Y)
  *uv = Eigen::Vector2d(fx * g * X + intrinsics_.cx, fy * g * Y + intrinsics_.cy);
  if (d_uv_d_p) {
    const double rho2 = r2 + Z * Z;
    const double dth_dr = Z / rho2, dth_dz = -r / rho2;
    // g(r, theta(r, Z)): dg/dr = (dtd * dth_dr * r - td) / r^2, dg/dZ = dtd * dth_dz / r.
    const double dg_dr = (dtd * dth_dr * r - td) / r2;
    const double dg_dx = dg_dr * X / r, dg_dy = dg_dr * Y / r, dg_dz = dtd * dth_dz / r;
    *d_uv_d_p << fx * (g + X * dg_dx), fx * X * dg_dy, fx * X * dg_dz,  //
        fy * Y * dg_dx, fy * (g + Y * dg_dy), fy * Y * dg_dz;
  }
  return true;
}

bool FisheyeEquidistantCamera::Unproject(const Eigen::Vector2d& uv, Eigen::Vector3d* bearing) const {
  const double xd = (uv.x() - intrinsics_.cx) / intrinsics_.fx;
  const double yd = (uv.y() - intrinsics_.cy) / intrinsics_.fy;
  const double td = std::sqrt(xd * xd + yd * yd);
  if (td < kAxisEpsilon) {
    *bearing = Eigen::Vector3d(xd, yd, 1.0).normalized();
    return true;
  }
  if (td >= ThetaD(max_theta_rad_)) return false;
  double theta = td;  // Newton on theta_d(theta) = td; monotonic below max_theta_rad_
  for (int i = 0; i < 30; ++i) {
    double d = 0;
    const double f = ThetaD(theta, &d) - td;
    if (std::abs(f) < 1e-14) break;
    theta -= f / d;
    theta = std::min(std::max(theta, 0.0), max_theta_rad_);
  }
  if (std::abs(ThetaD(theta) - td) > 1e-10) return false;
  const double s = std::sin(theta) / td;
  *bearing = Eigen::Vector3d(xd * s, yd * s, std::cos(theta));
  return true;
}

}  // namespace ccm
