// Synthetic correspondences with exact ground truth for the solver tests and benchmark:
// points seen by real camera models (EuRoC-like pinhole with distortion, TUM-VI-like
// fisheye), pixel noise added before unprojection, a fraction replaced by outliers.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/camera_presets.h"
#include "slam_core/geometry/se3.h"

namespace ccm::solvers::test {

inline CameraIntrinsics EurocLikePinhole() { return EurocCam0Intrinsics(); }

inline CameraIntrinsics TumViLikeFisheye() { return TumViFisheyeIntrinsics(); }

/// Two-view (or 2D-3D) data: bearings of the same world points in two cameras.
struct TwoViewData {
  SE3 world_from_cam1, world_from_cam2;
  std::vector<Eigen::Vector3d> points_world;  // ground truth (outliers keep theirs too)
  std::vector<Eigen::Vector3d> bearings1, bearings2;
  std::vector<bool> is_outlier;
};

class SceneGenerator {
 public:
  explicit SceneGenerator(unsigned seed, const CameraIntrinsics& intr = EurocLikePinhole())
      : rng_(seed), camera_(MakeCamera(intr)) {}

  const CameraModel& camera() const { return *camera_; }
  std::mt19937& rng() { return rng_; }

  double Uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  double Gaussian(double sigma) { return std::normal_distribution<double>(0.0, sigma)(rng_); }

  /// Bearing of a noisy observation of p_cam; false if it does not land in the image.
  bool Observe(const Eigen::Vector3d& p_cam, double noise_px, Eigen::Vector3d* bearing) {
    Eigen::Vector2d uv;
    if (!camera_->Project(p_cam, &uv) || !camera_->InImage(uv, 5.0)) return false;
    uv += Eigen::Vector2d(Gaussian(noise_px), Gaussian(noise_px));
    return camera_->Unproject(uv, bearing);
  }

  /// Bearing of a random pixel (an outlier match).
  Eigen::Vector3d RandomBearing() {
    Eigen::Vector3d b;
    while (!camera_->Unproject(Eigen::Vector2d(Uniform(5, camera_->width() - 6), Uniform(5, camera_->height() - 6)), &b)) {
    }
    return b;
  }

  /// Point seen by cam1 at a random pixel and depth in [min_depth, max_depth].
  Eigen::Vector3d PointInView(const SE3& world_from_cam, double min_depth, double max_depth) {
    Eigen::Vector3d b = RandomBearing();
    return world_from_cam * (b * Uniform(min_depth, max_depth) / std::max(b.z(), 0.2));
  }

  /// n correspondences visible in both cameras. `plane`: points on a plane through
  /// (0,0,5) with normal `plane_normal` (in cam1) instead of a depth range.
  TwoViewData MakeTwoView(const SE3& world_from_cam2, int n, double noise_px, double outlier_ratio,
                          bool plane = false, Eigen::Vector3d plane_normal = Eigen::Vector3d(0, 0.3, -1)) {
    TwoViewData d;
    d.world_from_cam2 = world_from_cam2;
    const SE3 cam2_from_world = world_from_cam2.inverse();
    plane_normal.normalize();
    const Eigen::Vector3d plane_point(0, 0, 5);
    while (static_cast<int>(d.bearings1.size()) < n) {
      Eigen::Vector3d p = PointInView(SE3(), 3.0, 9.0);
      if (plane) {  // slide p along its ray onto the plane
        const double s = plane_normal.dot(plane_point) / plane_normal.dot(p);
        if (!(s > 0)) continue;
        p *= s;
      }
      Eigen::Vector3d f1, f2;
      if (!Observe(p, noise_px, &f1) || !Observe(cam2_from_world * p, noise_px, &f2)) continue;
      const bool outlier = Uniform(0, 1) < outlier_ratio;
      if (outlier) f2 = RandomBearing();
      d.points_world.push_back(p);
      d.bearings1.push_back(f1);
      d.bearings2.push_back(f2);
      d.is_outlier.push_back(outlier);
    }
    return d;
  }

 private:
  std::mt19937 rng_;
  std::unique_ptr<CameraModel> camera_;
};

inline double RotationErrorDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a * b.conjugate()).angle() * 180.0 / M_PI;
}

inline double DirectionErrorDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

inline SE3 MakePose(double rx_deg, double ry_deg, double rz_deg, const Eigen::Vector3d& t) {
  const double k = M_PI / 180.0;
  const Eigen::Quaterniond q = Eigen::AngleAxisd(rz_deg * k, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(ry_deg * k, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(rx_deg * k, Eigen::Vector3d::UnitX());
  return SE3(q, t);
}

}  // namespace ccm::solvers::test
