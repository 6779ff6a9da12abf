#include "slam_core/optimization/bundle_adjustment.h"

#include <gtest/gtest.h>

#include <ceres/numeric_diff_cost_function.h>

#include "slam_core/optimization/pose_manifold.h"
#include "slam_core/optimization/reprojection_cost.h"
#include "slam_core/optimization/reprojection_cost_analytic.h"
#include "synthetic_scene.h"

namespace ccm::opt {
namespace {

using testing::MakeScene;
using testing::RotationAngleDeg;
using testing::SceneOptions;

// The problem's poses against the scene's truth after a Sim(3) alignment.
testing::PoseErrors AlignedErrorsOf(const BundleProblem& p, const testing::Scene& scene) {
  std::vector<SE3> poses;
  for (const PoseBlock& pose : p.poses) poses.push_back(pose.world_from_cam);
  return testing::AlignedPoseErrors(poses, scene.gt_world_from_cam);
}

// The Jet chain rule through CameraModel::Project must equal numeric differentiation.
TEST(ReprojectionCost, AutodiffJacobianMatchesNumericForBothCameraModels) {
  for (const auto& camera : {testing::MakeTestCamera(), testing::MakeTestFisheye()}) {
    const Se3Block pose = PackSe3(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
                                      Eigen::Vector3d(0.1, -0.2, 0.3)));
    const Eigen::Vector3d X(0.4, -0.3, 3.0);
    std::unique_ptr<ceres::CostFunction> ad(ReprojectionError::Create(camera.get(), Eigen::Vector2d(300, 200), 1.5));
    ceres::NumericDiffOptions nd_options;
    std::unique_ptr<ceres::CostFunction> nd(
        new ceres::NumericDiffCostFunction<ReprojectionError, ceres::CENTRAL, 2, 7, 3>(
            new ReprojectionError(camera.get(), Eigen::Vector2d(300, 200), 1.5)));
    const double* params[2] = {pose.data(), X.data()};
    double r_ad[2], r_nd[2], ja0[14], ja1[6], jn0[14], jn1[6];
    double* ja[2] = {ja0, ja1};
    double* jn[2] = {jn0, jn1};
    ASSERT_TRUE(ad->Evaluate(params, r_ad, ja));
    ASSERT_TRUE(nd->Evaluate(params, r_nd, jn));
    for (int k = 0; k < 14; ++k) EXPECT_NEAR(ja0[k], jn0[k], 1e-5 * (1.0 + std::abs(jn0[k])));
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(ja1[k], jn1[k], 1e-5 * (1.0 + std::abs(jn1[k])));
  }
}

// The analytic cost must give the same residual and the same tangent-space Jacobian
// (ambient Jacobian times the manifold's PlusJacobian) as the autodiff functor.
TEST(ReprojectionCost, AnalyticMatchesAutodiffInTangentSpace) {
  std::unique_ptr<ceres::Manifold> manifold(NewSe3Manifold());
  for (const auto& camera : {testing::MakeTestCamera(), testing::MakeTestFisheye()}) {
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::Vector3d axis = Eigen::Vector3d(1, 2 - trial, 3 + trial).normalized();
      const Se3Block pose = PackSe3(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.2 + 0.5 * trial, axis)),
                                        Eigen::Vector3d(0.1 * trial, -0.2, 0.3)));
      const Eigen::Vector3d X = UnpackSe3(pose).inverse() * Eigen::Vector3d(0.3 - 0.1 * trial, -0.2, 2.0 + trial);
      std::unique_ptr<ceres::CostFunction> ad(ReprojectionError::Create(camera.get(), Eigen::Vector2d(300, 200), 1.2));
      std::unique_ptr<ceres::CostFunction> an(ReprojectionCostAnalytic::Create(camera.get(), Eigen::Vector2d(300, 200), 1.2));
      const double* params[2] = {pose.data(), X.data()};
      Eigen::Matrix<double, 2, 7, Eigen::RowMajor> jpa, jpn;
      Eigen::Matrix<double, 2, 3, Eigen::RowMajor> jxa, jxn;
      Eigen::Vector2d ra, rn;
      double* ja[2] = {jpa.data(), jxa.data()};
      double* jn[2] = {jpn.data(), jxn.data()};
      ASSERT_TRUE(ad->Evaluate(params, ra.data(), ja));
      ASSERT_TRUE(an->Evaluate(params, rn.data(), jn));
      Eigen::Matrix<double, 7, 6, Eigen::RowMajor> plus;
      ASSERT_TRUE(manifold->PlusJacobian(pose.data(), plus.data()));
      EXPECT_LT((ra - rn).norm(), 1e-9);
      EXPECT_LT((jpa * plus - jpn * plus).norm(), 1e-7 * (1.0 + (jpa * plus).norm()));
      EXPECT_LT((jxa - jxn).norm(), 1e-7 * (1.0 + jxa.norm()));
      // Pose-only twins.
      std::unique_ptr<ceres::CostFunction> pad(
          PoseOnlyReprojectionError::Create(camera.get(), X, Eigen::Vector2d(300, 200), 1.2));
      std::unique_ptr<ceres::CostFunction> pan(PoseOnlyCostAnalytic::Create(camera.get(), X, Eigen::Vector2d(300, 200), 1.2));
      ASSERT_TRUE(pad->Evaluate(params, ra.data(), ja));
      ASSERT_TRUE(pan->Evaluate(params, rn.data(), jn));
      EXPECT_LT((ra - rn).norm(), 1e-9);
      EXPECT_LT((jpa * plus - jpn * plus).norm(), 1e-7 * (1.0 + (jpa * plus).norm()));
    }
  }
}

// An inverse-depth point must reproject exactly where its XYZ twin does, with the Jacobian of
// numeric differentiation, also for a point far out (inverse depth 1e-3).
TEST(ReprojectionCost, InverseDepthMatchesXyzAndNumericJacobian) {
  for (const auto& camera : {testing::MakeTestCamera(), testing::MakeTestFisheye()}) {
    for (const double depth : {4.0, 1000.0}) {
      const SE3 anchor_from_world(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d(0, 1, 0))),
                                  Eigen::Vector3d(0.3, -0.1, 0.2));
      const SE3 cam_from_world(Eigen::Quaterniond(Eigen::AngleAxisd(0.25, Eigen::Vector3d(0.1, 1, 0).normalized())),
                               Eigen::Vector3d(-0.2, 0.0, 0.4));
      const Eigen::Vector3d abr(0.1, -0.05, 1.0 / depth);
      const Eigen::Vector3d X = anchor_from_world.inverse() * (Eigen::Vector3d(abr.x(), abr.y(), 1.0) * depth);
      const Se3Block a = PackSe3(anchor_from_world), o = PackSe3(cam_from_world);
      const Eigen::Vector2d z(300, 200);
      std::unique_ptr<ceres::CostFunction> id(InverseDepthReprojectionError::Create(camera.get(), z, 1.5));
      std::unique_ptr<ceres::CostFunction> xyz(ReprojectionError::Create(camera.get(), z, 1.5));
      std::unique_ptr<ceres::CostFunction> nd(
          new ceres::NumericDiffCostFunction<InverseDepthReprojectionError, ceres::CENTRAL, 2, 7, 7, 3>(
              new InverseDepthReprojectionError(camera.get(), z, 1.5)));
      const double* params[3] = {a.data(), o.data(), abr.data()};
      const double* xyz_params[2] = {o.data(), X.data()};
      double r_id[2], r_xyz[2], r_nd[2], ja0[14], ja1[14], ja2[6], jn0[14], jn1[14], jn2[6];
      double* ja[3] = {ja0, ja1, ja2};
      double* jn[3] = {jn0, jn1, jn2};
      ASSERT_TRUE(id->Evaluate(params, r_id, ja));
      ASSERT_TRUE(xyz->Evaluate(xyz_params, r_xyz, nullptr));
      ASSERT_TRUE(nd->Evaluate(params, r_nd, jn));
      for (int k = 0; k < 2; ++k) EXPECT_NEAR(r_id[k], r_xyz[k], 1e-6 * (1.0 + std::abs(r_xyz[k]))) << depth;
      for (int k = 0; k < 14; ++k) EXPECT_NEAR(ja0[k], jn0[k], 1e-4 * (1.0 + std::abs(jn0[k]))) << depth;
      for (int k = 0; k < 14; ++k) EXPECT_NEAR(ja1[k], jn1[k], 1e-4 * (1.0 + std::abs(jn1[k]))) << depth;
      for (int k = 0; k < 6; ++k) EXPECT_NEAR(ja2[k], jn2[k], 1e-4 * (1.0 + std::abs(jn2[k]))) << depth;
      // The anchor's own view depends on the ray only.
      std::unique_ptr<ceres::CostFunction> own(AnchorRayReprojectionError::Create(camera.get(), z, 1.5));
      std::unique_ptr<ceres::CostFunction> own_xyz(ReprojectionError::Create(camera.get(), z, 1.5));
      const double* own_params[1] = {abr.data()};
      const double* own_xyz_params[2] = {a.data(), X.data()};
      ASSERT_TRUE(own->Evaluate(own_params, r_id, nullptr));
      ASSERT_TRUE(own_xyz->Evaluate(own_xyz_params, r_xyz, nullptr));
      for (int k = 0; k < 2; ++k) EXPECT_NEAR(r_id[k], r_xyz[k], 1e-6 * (1.0 + std::abs(r_xyz[k]))) << depth;
    }
  }
}

TEST(LocalBundleAdjustment, ReducesPerturbedWindowToNoiseLevelAndFlagsOutliers) {
  SceneOptions so;
  so.num_keyframes = 30;
  so.num_points = 2500;
  so.pixel_noise_px = 1.0;
  so.max_pyramid_level = 3;  // sigma 1..1.73 px; noise scales with sigma
  so.seed = 3;
  testing::Scene scene = MakeScene(so);
  BundleProblem& p = scene.problem;
  // Window: keyframes 10..19 free; all others are the fixed periphery.
  for (PoseBlock& pose : p.poses) pose.fixed = pose.id < 10 || pose.id >= 20;
  std::mt19937 rng(11);
  // 3% gross outliers (20-40 px).
  std::uniform_real_distribution<double> u01(0, 1), ang(0, 2 * M_PI), mag(20, 40);
  std::vector<bool> is_outlier(p.observations.size(), false);
  for (size_t i = 0; i < p.observations.size(); ++i) {
    if (u01(rng) >= 0.03) continue;
    const double a = ang(rng);
    p.observations[i].uv_px += mag(rng) * Eigen::Vector2d(std::cos(a), std::sin(a));
    is_outlier[i] = true;
  }
  std::vector<bool> true_inliers(is_outlier.size());
  for (size_t i = 0; i < is_outlier.size(); ++i) true_inliers[i] = !is_outlier[i];
  const double rmse_truth = ReprojectionRmsePx(p, &true_inliers);
  testing::Perturb(&p, 1.0, 0.05, 0.05, &rng);
  const double rmse_before = ReprojectionRmsePx(p, &true_inliers);
  const OptimizationSummary s = LocalBundleAdjustment(&p);
  ASSERT_TRUE(s.usable) << s.message;
  const double rmse_after = ReprojectionRmsePx(p, &true_inliers);
  EXPECT_GT(rmse_before, 5.0 * rmse_truth);
  EXPECT_LT(rmse_after, 1.05 * rmse_truth) << "truth " << rmse_truth << " before " << rmse_before;
  // A point seen only a few times can absorb a gross error by moving along its ray (ORB-SLAM
  // has the same weakness), so all outliers must be found where the point has >= 5
  // observations, and nearly all overall.
  std::vector<int> obs_per_point(p.points.size(), 0);
  for (const Observation& o : p.observations) ++obs_per_point[o.point_index];
  int flagged = 0, outliers = 0, well_observed = 0, well_observed_flagged = 0;
  for (size_t i = 0; i < is_outlier.size(); ++i) {
    if (!is_outlier[i]) continue;
    ++outliers;
    flagged += s.inlier[i] ? 0 : 1;
    if (obs_per_point[p.observations[i].point_index] < 5) continue;
    ++well_observed;
    well_observed_flagged += s.inlier[i] ? 0 : 1;
  }
  EXPECT_EQ(well_observed_flagged, well_observed);
  EXPECT_GE(flagged, 0.97 * outliers);
  EXPECT_GT(well_observed, 0.8 * outliers);
  // Periphery poses did not move.
  for (size_t i = 0; i < p.poses.size(); ++i) {
    if (!p.poses[i].fixed) continue;
    EXPECT_EQ(p.poses[i].world_from_cam.translation(), scene.gt_world_from_cam[i].translation());
  }
}

TEST(GlobalBundleAdjustment, ConvergesToGroundTruth) {
  SceneOptions so;
  so.num_keyframes = 40;
  so.num_points = 4500;  // ~2,800 survive the >= 2 observations filter
  so.pixel_noise_px = 0.5;
  so.seed = 5;
  testing::Scene scene = MakeScene(so);
  BundleProblem& p = scene.problem;
  p.poses[0].fixed = true;  // gauge: first pose; the free scale is removed by Sim(3) alignment
  std::mt19937 rng(13);
  testing::Perturb(&p, 1.0, 0.05, 0.1, &rng);
  std::vector<SE3> before;
  for (const PoseBlock& pose : p.poses) before.push_back(pose.world_from_cam);
  const testing::PoseErrors e0 = testing::AlignedPoseErrors(before, scene.gt_world_from_cam);
  BundleAdjusterOptions options = GlobalBaDefaults();
  options.robust_iterations = 30;
  const OptimizationSummary s = GlobalBundleAdjustment(&p, options);
  ASSERT_TRUE(s.usable) << s.message;
  const testing::PoseErrors e = AlignedErrorsOf(p, scene);
  EXPECT_GT(e0.max_position_m, 0.05);
  EXPECT_LT(e.max_position_m, 0.01) << "rmse " << e.rmse_position_m;
  EXPECT_LT(e.max_rotation_deg, 0.1);
  EXPECT_LT(s.final_cost, 0.01 * s.initial_cost);
  EXPECT_GT(s.num_inliers, 0.9 * p.observations.size());
}

// Every point as an inverse depth from the first keyframe that sees it: the same optimum.
TEST(GlobalBundleAdjustment, InverseDepthPointsConvergeToGroundTruth) {
  SceneOptions so;
  so.num_keyframes = 30;
  so.pixel_noise_px = 0.5;
  so.seed = 7;
  testing::Scene scene = MakeScene(so);
  BundleProblem& p = scene.problem;
  p.poses[0].fixed = true;
  std::mt19937 rng(29);
  testing::Perturb(&p, 1.0, 0.05, 0.1, &rng);
  for (const Observation& o : p.observations) {
    int& anchor = p.points[o.point_index].anchor_pose;
    anchor = anchor < 0 ? o.pose_index : std::min(anchor, o.pose_index);
  }
  BundleAdjusterOptions options = GlobalBaDefaults();
  options.robust_iterations = 30;
  const OptimizationSummary s = GlobalBundleAdjustment(&p, options);
  ASSERT_TRUE(s.usable) << s.message;
  const testing::PoseErrors e = AlignedErrorsOf(p, scene);
  EXPECT_LT(e.max_position_m, 0.01) << "rmse " << e.rmse_position_m;
  EXPECT_LT(e.max_rotation_deg, 0.1);
  EXPECT_GT(s.num_inliers, 0.9 * p.observations.size());
  EXPECT_LT(ReprojectionRmsePx(p), 0.8) << "the points were written back where the BA left them";
  p.points[0].anchor_pose = static_cast<int>(p.poses.size());
  EXPECT_NE(ValidateProblem(p).find("anchor"), std::string::npos);
}

// Collaborative SLAM: keyframes of different agents carry different camera models.
TEST(GlobalBundleAdjustment, MixedPinholeAndFisheyeKeyframes) {
  SceneOptions so;
  so.num_keyframes = 24;
  so.num_points = 3000;
  so.pixel_noise_px = 0.0;
  so.seed = 17;
  testing::Scene scene = MakeScene(so);
  BundleProblem& p = scene.problem;
  p.cameras.push_back(testing::MakeTestFisheye());
  std::mt19937 rng(19);
  std::normal_distribution<double> n(0.0, 0.5);
  std::vector<Observation> kept;
  for (PoseBlock& pose : p.poses) pose.camera_index = static_cast<int>(pose.id % 2);
  for (Observation o : p.observations) {
    const PoseBlock& pose = p.poses[o.pose_index];
    Eigen::Vector2d uv;
    const CameraModel& cam = *p.cameras[pose.camera_index];
    if (!cam.Project(pose.world_from_cam.inverse() * scene.gt_points_w[o.point_index], &uv) || !cam.InImage(uv)) continue;
    o.uv_px = uv + Eigen::Vector2d(n(rng), n(rng));
    kept.push_back(o);
  }
  p.observations = kept;
  p.poses[0].fixed = true;
  testing::Perturb(&p, 1.0, 0.05, 0.1, &rng);
  BundleAdjusterOptions options = GlobalBaDefaults();
  options.robust_iterations = 30;
  const OptimizationSummary s = GlobalBundleAdjustment(&p, options);
  ASSERT_TRUE(s.usable) << s.message;
  const testing::PoseErrors e = AlignedErrorsOf(p, scene);
  EXPECT_LT(e.max_position_m, 0.01);
  EXPECT_LT(e.max_rotation_deg, 0.1);
  EXPECT_LT(ReprojectionRmsePx(p), 0.8);  // 0.5 px noise per axis -> ~0.7 px RMSE
}

// A wide lens whose distortion polynomial folds inside the image (848 px across, f = 350,
// k1 = -0.2: no ray maps beyond ~300 px from the centre): a keypoint near that edge belongs
// to a point close to the fold. Project calls it invisible a hair further out, so with
// Project in the costs every step that moved such a point outwards failed to evaluate and
// Ceres rejected the whole step: global BAs of wide-camera maps made no step at all
// (2026-12-06). The costs use ProjectForCost, which continues the model smoothly.
TEST(GlobalBundleAdjustment, AnObservationAtTheDistortionFoldDoesNotFreezeTheSteps) {
  SceneOptions so;
  so.num_keyframes = 30;
  so.pixel_noise_px = 0.0;
  so.seed = 23;
  testing::Scene scene = MakeScene(so);
  BundleProblem& p = scene.problem;
  CameraIntrinsics k;
  k.width_px = 848;
  k.height_px = 480;
  k.fx = k.fy = 350;
  k.cx = 424;
  k.cy = 240;
  k.distortion = {-0.2, 0.0, 0.0, 0.0};
  p.cameras[0] = std::shared_ptr<const CameraModel>(MakeCamera(k));
  const CameraModel& wide = *p.cameras[0];
  const double fold_r = std::sqrt(1.0 / 0.6);  // d(r (1 + k1 r^2)) / dr = 0
  std::mt19937 rng(31);
  std::normal_distribution<double> noise(0.0, 0.5);
  // One more keyframe beside keyframe 10, turned so that a point keyframe 10 sees lies just
  // past the fold (its keypoint at the edge of the image circle); it sees everything else in
  // its view as usual. The point starts just inside the fold: its observation is valid there
  // and the others pull it across.
  const int fold_point = std::find_if(p.observations.begin(), p.observations.end(), [](const Observation& o) {
                           return o.pose_index == 10;
                         })->point_index;
  const SE3& beside = p.poses[10].world_from_cam;
  const Eigen::Vector3d bearing = (beside.inverse() * scene.gt_points_w[fold_point]).normalized();
  const Eigen::Quaterniond turn =
      Eigen::Quaterniond::FromTwoVectors(bearing, Eigen::Vector3d(fold_r * 1.001, 0.0, 1.0).normalized());
  const SE3 turned_cam_from_world(turn * beside.inverse().rotation(), turn * beside.inverse().translation());
  p.poses.push_back(PoseBlock{999, turned_cam_from_world.inverse(), false, 0});
  scene.gt_world_from_cam.push_back(p.poses.back().world_from_cam);
  const int turned = static_cast<int>(p.poses.size()) - 1;
  std::vector<Observation> all = p.observations;
  for (size_t i = 0; i < p.points.size(); ++i) all.push_back(Observation{turned, static_cast<int>(i), {}, 1.0});
  p.observations.clear();
  for (Observation o : all) {
    const Eigen::Vector3d p_cam = p.poses[o.pose_index].world_from_cam.inverse() * scene.gt_points_w[o.point_index];
    Eigen::Vector2d uv;
    if (o.pose_index == turned && o.point_index == fold_point) {
      ASSERT_FALSE(wide.Project(p_cam, &uv)) << "the point is past the fold";
      ASSERT_TRUE(wide.ProjectForCost(p_cam, &uv));
      ASSERT_TRUE(wide.InImage(uv));
    } else if (!wide.Project(p_cam, &uv) || !wide.InImage(uv)) {
      continue;
    } else {
      uv += Eigen::Vector2d(noise(rng), noise(rng));
    }
    p.observations.push_back(Observation{o.pose_index, o.point_index, uv, 1.0});
  }
  p.poses[0].fixed = true;
  testing::Perturb(&p, 0.1, 0.01, 0.02, &rng);
  p.poses[turned].world_from_cam = scene.gt_world_from_cam[turned];
  const Eigen::Vector3d inside = Eigen::Vector3d(fold_r * 0.999, 0.0, 1.0).normalized() *
                                 (turned_cam_from_world * scene.gt_points_w[fold_point]).norm();
  p.points[fold_point].position_w = turned_cam_from_world.inverse() * inside;
  BundleAdjusterOptions options = GlobalBaDefaults();
  options.robust_iterations = 20;
  const OptimizationSummary s = GlobalBundleAdjustment(&p, options);
  ASSERT_TRUE(s.usable) << s.message;
  EXPECT_LT(s.rejected_steps, s.iterations / 2) << s.message;
  const testing::PoseErrors e = AlignedErrorsOf(p, scene);
  EXPECT_LT(e.max_position_m, 0.01) << "rmse " << e.rmse_position_m;
  EXPECT_LT(e.max_rotation_deg, 0.1);
}

TEST(BundleAdjust, RejectsInvalidProblem) {
  BundleProblem p;
  p.cameras.push_back(testing::MakeTestCamera());
  p.poses.push_back(PoseBlock{});
  p.observations.push_back(Observation{0, 3, Eigen::Vector2d(1, 1), 1.0});
  const OptimizationSummary s = BundleAdjust(&p, LocalBaDefaults());
  EXPECT_FALSE(s.usable);
  EXPECT_NE(s.message.find("out of range"), std::string::npos);
}

}  // namespace
}  // namespace ccm::opt
