// Synthetic ground truth for the optimization tests and benchmark: keyframes on a circular
// arc looking outwards at a cylindrical "wall" of points with depth relief (boxes), seen
// through a EuRoC-like pinhole-radtan camera made by ccm::MakeCamera.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "slam_core/optimization/bundle_problem.h"

namespace ccm::opt::testing {

struct SceneOptions {
  int num_keyframes = 40;
  int num_points = 3000;
  double radius_m = 10.0;          ///< trajectory circle radius
  double wall_distance_m = 3.0;    ///< mean distance from the trajectory to the wall
  double relief_m = 1.5;           ///< points lie within +- relief of the wall
  double arc_rad = 1.2;            ///< angle covered by the trajectory (2*pi: closed loop)
  double pixel_noise_px = 0.5;     ///< std of the Gaussian noise added to measurements
  int max_pyramid_level = 0;       ///< levels drawn uniformly in [0, max]; sigma = 1.2^level
  std::uint32_t seed = 1;
};

/// Ground truth plus noisy measurements. problem.poses/points hold the ground truth;
/// observations carry noisy pixels (noise std = pixel_noise_px * sigma_px).
struct Scene {
  BundleProblem problem;
  std::vector<SE3> gt_world_from_cam;
  std::vector<Eigen::Vector3d> gt_points_w;
};

std::shared_ptr<const CameraModel> MakeTestCamera();
/// A 752x480 equidistant fisheye (300 px focal length, mild distortion).
std::shared_ptr<const CameraModel> MakeTestFisheye();
Scene MakeScene(const SceneOptions& options);

/// Perturbs non-fixed poses (rotation_deg / translation_m std per axis) and points.
void Perturb(BundleProblem* problem, double rotation_deg, double translation_m, double point_m, std::mt19937* rng);

/// Position and rotation errors of the problem's poses against ground truth, after
/// aligning the estimated camera centres to the true ones with a Sim(3) (Umeyama).
struct PoseErrors {
  double max_position_m = 0;
  double rmse_position_m = 0;
  double max_rotation_deg = 0;
};
PoseErrors AlignedPoseErrors(const std::vector<SE3>& estimate, const std::vector<SE3>& truth);

double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace ccm::opt::testing
