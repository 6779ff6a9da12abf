#include "synthetic_scene.h"

#include <cmath>

#include <Eigen/Geometry>
#include "slam_core/geometry/camera_presets.h"

namespace ccm::opt::testing {

std::shared_ptr<const CameraModel> MakeTestCamera() {
  return std::shared_ptr<const CameraModel>(MakeCamera(EurocCam0Intrinsics()));
}

std::shared_ptr<const CameraModel> MakeTestFisheye() {
  CameraIntrinsics k;
  k.type = CameraType::kFisheyeEquidistant;
  k.width_px = 752;
  k.height_px = 480;
  k.fx = 300;
  k.fy = 300;
  k.cx = 376;
  k.cy = 240;
  k.distortion = {0.01, -0.005, 0.001, -0.0002};
  return std::shared_ptr<const CameraModel>(MakeCamera(k));
}

namespace {

// Camera on the circle at angle theta, looking outwards (z radial, y down = -world z).
SE3 CirclePose(double radius, double theta, double height) {
  const Eigen::Vector3d z(std::cos(theta), std::sin(theta), 0.0);
  const Eigen::Vector3d y(0.0, 0.0, -1.0);
  Eigen::Matrix3d R;
  R.col(0) = y.cross(z);
  R.col(1) = y;
  R.col(2) = z;
  return SE3(R, Eigen::Vector3d(radius * std::cos(theta), radius * std::sin(theta), height));
}

Eigen::Quaterniond SmallRotation(double std_rad, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, std_rad);
  const Eigen::Vector3d w(n(*rng), n(*rng), n(*rng));
  const double a = w.norm();
  return a < 1e-15 ? Eigen::Quaterniond::Identity() : Eigen::Quaterniond(Eigen::AngleAxisd(a, w / a));
}

}  // namespace

Scene MakeScene(const SceneOptions& o) {
  Scene scene;
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_int_distribution<int> level(0, o.max_pyramid_level);
  BundleProblem& p = scene.problem;
  p.cameras.push_back(MakeTestCamera());
  const bool closed = o.arc_rad >= 2.0 * M_PI - 1e-9;
  const double step = closed ? o.arc_rad / o.num_keyframes : o.arc_rad / std::max(1, o.num_keyframes - 1);
  for (int i = 0; i < o.num_keyframes; ++i) {
    SE3 T = CirclePose(o.radius_m, i * step, 0.2 * u(rng));
    T = SE3(T.rotation() * SmallRotation(0.05, &rng), T.translation());
    scene.gt_world_from_cam.push_back(T);
    p.poses.push_back(PoseBlock{static_cast<std::uint64_t>(i), T, false, 0});
  }
  // Points over the trajectory's angular span plus the field of view on both ends.
  const double margin = closed ? 0.0 : 0.6;
  const double wall = o.radius_m + o.wall_distance_m;
  std::vector<SE3> cam_from_world;
  for (const SE3& T : scene.gt_world_from_cam) cam_from_world.push_back(T.inverse());
  const CameraModel& cam = *p.cameras[0];
  for (int k = 0; k < o.num_points; ++k) {
    const double theta = -margin + (o.arc_rad + 2.0 * margin) * 0.5 * (u(rng) + 1.0);
    const double r = wall + o.relief_m * u(rng);
    const Eigen::Vector3d X(r * std::cos(theta), r * std::sin(theta), 1.3 * u(rng));
    std::vector<Observation> obs;
    for (int i = 0; i < o.num_keyframes; ++i) {
      Eigen::Vector2d uv;
      if (!cam.Project(cam_from_world[i] * X, &uv) || !cam.InImage(uv, 8.0)) continue;
      const double sigma = SigmaForPyramidLevel(level(rng));
      const Eigen::Vector2d noise(n01(rng), n01(rng));
      obs.push_back(Observation{i, 0, uv + o.pixel_noise_px * sigma * noise, sigma});
    }
    if (obs.size() < 2) continue;
    const int index = static_cast<int>(p.points.size());
    p.points.push_back(PointBlock{static_cast<std::uint64_t>(index), X, false});
    scene.gt_points_w.push_back(X);
    for (Observation& ob : obs) {
      ob.point_index = index;
      p.observations.push_back(ob);
    }
  }
  return scene;
}

void Perturb(BundleProblem* problem, double rotation_deg, double translation_m, double point_m, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  for (PoseBlock& pose : problem->poses) {
    if (pose.fixed) continue;
    const Eigen::Vector3d dt(n(*rng), n(*rng), n(*rng));
    pose.world_from_cam = SE3(pose.world_from_cam.rotation() * SmallRotation(rotation_deg * M_PI / 180.0, rng),
                              pose.world_from_cam.translation() + translation_m * dt);
  }
  for (PointBlock& point : problem->points) {
    if (point.fixed) continue;
    point.position_w += point_m * Eigen::Vector3d(n(*rng), n(*rng), n(*rng));
  }
}

double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b) * 180.0 / M_PI;
}

PoseErrors AlignedPoseErrors(const std::vector<SE3>& estimate, const std::vector<SE3>& truth) {
  const int n = static_cast<int>(estimate.size());
  Eigen::Matrix3Xd src(3, n), dst(3, n);
  for (int i = 0; i < n; ++i) {
    src.col(i) = estimate[i].translation();
    dst.col(i) = truth[i].translation();
  }
  const Eigen::Matrix4d S = Eigen::umeyama(src, dst, true);
  const Eigen::Matrix3d sR = S.topLeftCorner<3, 3>();
  const double s = std::cbrt(sR.determinant());
  const Eigen::Quaterniond q(Eigen::Matrix3d(sR / s));
  PoseErrors e;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = sR * src.col(i) + S.topRightCorner<3, 1>();
    const double d = (p - dst.col(i)).norm();
    sum += d * d;
    e.max_position_m = std::max(e.max_position_m, d);
    e.max_rotation_deg = std::max(e.max_rotation_deg, RotationAngleDeg(q * estimate[i].rotation(), truth[i].rotation()));
  }
  e.rmse_position_m = std::sqrt(sum / std::max(1, n));
  return e;
}

}  // namespace ccm::opt::testing
