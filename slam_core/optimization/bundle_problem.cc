#include "slam_core/optimization/bundle_problem.h"

#include <cmath>

namespace ccm::opt {

double SigmaForPyramidLevel(int level, double scale_factor) {
  return std::pow(scale_factor, level);
}

double ObservationChi2(const BundleProblem& problem, const Observation& obs) {
  const PoseBlock& pose = problem.poses[obs.pose_index];
  const CameraModel& camera = *problem.cameras[pose.camera_index];
  const Eigen::Vector3d p_cam = pose.world_from_cam.inverse() * problem.points[obs.point_index].position_w;
  Eigen::Vector2d uv;
  if (!camera.Project(p_cam, &uv)) return -1.0;
  return (uv - obs.uv_px).squaredNorm() / (obs.sigma_px * obs.sigma_px);
}

double ReprojectionRmsePx(const BundleProblem& problem, const std::vector<bool>* mask) {
  double sum = 0.0;
  int n = 0;
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    if (mask && !(*mask)[i]) continue;
    const Observation& obs = problem.observations[i];
    const double chi2 = ObservationChi2(problem, obs);
    if (chi2 < 0.0) continue;
    sum += chi2 * obs.sigma_px * obs.sigma_px;
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

std::string ValidateProblem(const BundleProblem& problem) {
  for (size_t i = 0; i < problem.cameras.size(); ++i) {
    if (!problem.cameras[i]) return "camera " + std::to_string(i) + " is null";
  }
  const int num_cameras = static_cast<int>(problem.cameras.size());
  for (size_t i = 0; i < problem.poses.size(); ++i) {
    const int c = problem.poses[i].camera_index;
    if (c < 0 || c >= num_cameras) return "pose " + std::to_string(i) + " has camera index out of range";
  }
  const int num_poses = static_cast<int>(problem.poses.size());
  const int num_points = static_cast<int>(problem.points.size());
  for (size_t i = 0; i < problem.points.size(); ++i) {
    const int a = problem.points[i].anchor_pose;
    if (a < -1 || a >= num_poses) return "point " + std::to_string(i) + " has an anchor pose out of range";
  }
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    const Observation& o = problem.observations[i];
    if (o.pose_index < 0 || o.pose_index >= num_poses || o.point_index < 0 || o.point_index >= num_points) {
      return "observation " + std::to_string(i) + " has an index out of range";
    }
    if (!(o.sigma_px > 0.0)) return "observation " + std::to_string(i) + " has sigma_px <= 0";
  }
  return "";
}

}  // namespace ccm::opt
