// The pose-only optimization of tracking (OptimizePose, slam_core/optimization/pose_optimizer.cc): outliers,
// both camera models, exact convergence, and the same minimum as Ceres.
#include <gtest/gtest.h>

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <random>

#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/optimization/pose_manifold.h"
#include "slam_core/optimization/reprojection_cost_analytic.h"
#include "synthetic_scene.h"

namespace ccm::opt {
namespace {

using testing::MakeScene;
using testing::RotationAngleDeg;
using testing::SceneOptions;

struct PoseOnlyCase {
  std::vector<PointObservation> obs;
  std::vector<bool> is_outlier;
  SE3 truth;
};

// Visible points of keyframe 5 with 1 px noise; 20% replaced by random pixels > 20 px off.
PoseOnlyCase MakePoseOnlyCase(const CameraModel& camera, std::uint32_t seed) {
  SceneOptions so;
  so.seed = seed;
  so.num_points = 2000;
  so.pixel_noise_px = 0.0;
  const testing::Scene scene = MakeScene(so);
  PoseOnlyCase c;
  c.truth = scene.gt_world_from_cam[5];
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> ux(0, camera.width() - 1), uy(0, camera.height() - 1), u01(0, 1);
  for (const Observation& o : scene.problem.observations) {
    if (o.pose_index != 5) continue;
    Eigen::Vector2d uv;
    const Eigen::Vector3d X = scene.gt_points_w[o.point_index];
    if (!camera.Project(c.truth.inverse() * X, &uv) || !camera.InImage(uv)) continue;
    const bool outlier = u01(rng) < 0.2;
    Eigen::Vector2d z = uv + Eigen::Vector2d(n(rng), n(rng));
    if (outlier) {
      do z = Eigen::Vector2d(ux(rng), uy(rng));
      while ((z - uv).norm() < 20.0);
    }
    c.obs.push_back(PointObservation{X, z, 1.0});
    c.is_outlier.push_back(outlier);
  }
  return c;
}

void ExpectPoseOnlyRecovers(const CameraModel& camera, std::uint32_t seed) {
  const PoseOnlyCase c = MakePoseOnlyCase(camera, seed);
  ASSERT_GT(c.obs.size(), 100u);
  // Initial guess: 10 cm and ~3 deg off.
  SE3 pose(c.truth.rotation() * Eigen::Quaterniond(Eigen::AngleAxisd(3.0 * M_PI / 180, Eigen::Vector3d(0.3, 1, 0.2).normalized())),
           c.truth.translation() + Eigen::Vector3d(0.06, -0.05, 0.06));
  const OptimizationSummary s = OptimizePose(camera, c.obs, &pose);
  ASSERT_TRUE(s.usable) << s.message;
  EXPECT_LT((pose.translation() - c.truth.translation()).norm(), 0.01);
  EXPECT_LT(RotationAngleDeg(pose.rotation(), c.truth.rotation()), 0.1);
  int outliers_flagged = 0, outliers = 0, inliers_kept = 0, inliers = 0;
  for (size_t i = 0; i < c.obs.size(); ++i) {
    if (c.is_outlier[i]) {
      ++outliers;
      outliers_flagged += s.inlier[i] ? 0 : 1;
    } else {
      ++inliers;
      inliers_kept += s.inlier[i] ? 1 : 0;
    }
  }
  EXPECT_EQ(outliers_flagged, outliers);           // every > 20 px outlier is flagged
  EXPECT_GT(inliers_kept, 0.9 * inliers);          // chi2 95% test keeps ~95% of inliers
}

TEST(OptimizePose, RecoversPoseWith20PercentOutliersPinhole) {
  ExpectPoseOnlyRecovers(*testing::MakeTestCamera(), 7);
}

TEST(OptimizePose, RecoversPoseWith20PercentOutliersFisheye) {
  ExpectPoseOnlyRecovers(*testing::MakeTestFisheye(), 8);
}

// Noise-free observations: the optimizer must reach the exact pose from 8 deg / 0.27 m off;
// a wrong tangent Jacobian would stall far from it in 4 x 10 steps.
TEST(OptimizePose, ReachesExactPoseWithoutNoiseFromLargeError) {
  const auto camera = testing::MakeTestCamera();
  PoseOnlyCase c = MakePoseOnlyCase(*camera, 11);
  for (size_t i = 0; i < c.obs.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera->Project(c.truth.inverse() * c.obs[i].point_w, &uv));
    c.obs[i].uv_px = uv;  // outliers included: all consistent now
  }
  SE3 pose(c.truth.rotation() * Eigen::Quaterniond(Eigen::AngleAxisd(8.0 * M_PI / 180, Eigen::Vector3d(1, -0.4, 0.3).normalized())),
           c.truth.translation() + Eigen::Vector3d(-0.2, 0.1, 0.15));
  const OptimizationSummary s = OptimizePose(*camera, c.obs, &pose);
  ASSERT_TRUE(s.usable) << s.message;
  EXPECT_LT((pose.translation() - c.truth.translation()).norm(), 1e-6);
  EXPECT_LT(RotationAngleDeg(pose.rotation(), c.truth.rotation()), 1e-5);
  EXPECT_LT(s.final_cost, 1e-9);
  EXPECT_EQ(s.num_inliers, static_cast<int>(c.obs.size()));
}

// The pose optimizer's own Levenberg-Marquardt (no ceres::Problem, for tracking's speed)
// must reach the minimum Ceres reaches on the same residuals: noisy observations, one plain
// round, both camera models, compared with a tightly converged Ceres solve.
TEST(OptimizePose, ReachesTheMinimumCeresReachesOnTheSameResiduals) {
  const auto pinhole = testing::MakeTestCamera();
  const auto fisheye = testing::MakeTestFisheye();
  for (const CameraModel* camera : {pinhole.get(), fisheye.get()}) {
    PoseOnlyCase c = MakePoseOnlyCase(*camera, 21);
    std::vector<PointObservation> inliers;
    for (size_t i = 0; i < c.obs.size(); ++i) {
      if (!c.is_outlier[i]) inliers.push_back(c.obs[i]);
    }
    ASSERT_GT(inliers.size(), 100u);
    const SE3 start(c.truth.rotation() * Eigen::Quaterniond(Eigen::AngleAxisd(2.0 * M_PI / 180, Eigen::Vector3d::UnitY())),
                    c.truth.translation() + Eigen::Vector3d(0.04, 0.02, -0.03));
    SE3 ours = start;
    PoseOptimizerOptions po;
    po.num_rounds = 1;  // one plain round: the pass alone
    po.iterations_per_round = 50;
    po.chi2_threshold = 1e9;
    const OptimizationSummary s = OptimizePose(*camera, inliers, &ours, po);
    ASSERT_TRUE(s.usable) << s.message;

    Se3Block block = PackSe3(start.inverse());
    ceres::Problem problem;
    for (const PointObservation& o : inliers) {
      problem.AddResidualBlock(PoseOnlyCostAnalytic::Create(camera, o.point_w, o.uv_px, o.sigma_px), nullptr, block.data());
    }
    problem.SetManifold(block.data(), NewSe3Manifold());
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 100;
    so.function_tolerance = so.gradient_tolerance = so.parameter_tolerance = 1e-14;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    const SE3 reference = UnpackSe3(block).inverse();
    EXPECT_LT((ours.translation() - reference.translation()).norm(), 1e-6);
    EXPECT_LT(RotationAngleDeg(ours.rotation(), reference.rotation()), 1e-5);
    EXPECT_NEAR(s.final_cost, summary.final_cost, 1e-6 * summary.final_cost);
    EXPECT_GT((ours.translation() - c.truth.translation()).norm(), 0.0);  // noise: not the truth itself
  }
}

TEST(OptimizePose, TooFewObservationsIsNotUsable) {
  SE3 pose;
  const OptimizationSummary s = OptimizePose(*testing::MakeTestCamera(), {}, &pose);
  EXPECT_FALSE(s.usable);
}

}  // namespace
}  // namespace ccm::opt
