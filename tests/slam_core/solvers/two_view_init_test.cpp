#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <functional>

#include "slam_core/solvers/homography.h"
#include "slam_core/solvers/two_view_init.h"
#include "tests/slam_core/solvers/synthetic_scene.h"

namespace ccm::solvers {
namespace {

using test::SceneGenerator;

TwoViewInitOptions InitOptions(const SceneGenerator& gen) {
  TwoViewInitOptions o;
  o.focal_px = gen.camera().intrinsics().fx;
  o.sigma_px = 1.0;
  return o;
}

// Mean relative 3D error of the triangulated points after fixing the unknown scale with
// the ground-truth baseline.
double MeanRelativePointError(const TwoViewInitResult& r, const test::TwoViewData& d) {
  const double scale = d.world_from_cam2.translation().norm();
  double sum = 0.0;
  int n = 0;
  for (size_t i = 0; i < r.points_cam1.size(); ++i) {
    if (!r.points_cam1[i] || d.is_outlier[i]) continue;
    sum += (*r.points_cam1[i] * scale - d.points_world[i]).norm() / d.points_world[i].norm();
    ++n;
  }
  return n > 0 ? sum / n : 1e9;
}

TEST(Homography, RansacRecoversPlaneInducedHomographyAndDecomposes) {
  SceneGenerator gen(51);
  const SE3 world_from_cam2 = test::MakePose(4, -6, 2, Eigen::Vector3d(0.5, 0.1, 0.1));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 500, 0.7, 0.4, /*plane=*/true);
  HomographyOptions o;
  o.ransac.focal_px = gen.camera().intrinsics().fx;
  o.ransac.threshold_px = 2.5;
  const HomographyResult h = EstimateHomography(d.bearings1, d.bearings2, o);
  ASSERT_TRUE(h.ok()) << h.message;
  int wrong = 0;
  for (size_t i = 0; i < d.is_outlier.size(); ++i) wrong += (h.inliers[i] == d.is_outlier[i]);
  EXPECT_LT(wrong, 0.1 * d.is_outlier.size());  // both transfer errors must pass: ~8 % of inliers drop at 0.7 px
  // One of the decompositions is the true motion (translation up to the plane distance).
  const SE3 gt = world_from_cam2.inverse();
  double best = 1e9;
  for (const HomographyMotion& m : DecomposeHomography(h.cam2_H_cam1)) {
    const double rot = test::RotationErrorDeg(m.cam2_from_cam1.rotation(), gt.rotation());
    const double dir = test::DirectionErrorDeg(m.cam2_from_cam1.translation(), gt.translation());
    if (rot < 0.5) best = std::min(best, dir);
  }
  EXPECT_LT(best, 2.0);
}

TEST(TwoViewInit, PlanarSceneChoosesHomographyAndRecoversMotion) {
  SceneGenerator gen(52);
  const SE3 world_from_cam2 = test::MakePose(4, -6, 2, Eigen::Vector3d(0.6, 0.1, 0.1));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 500, 0.5, 0.3, /*plane=*/true);
  const TwoViewInitResult r = InitializeTwoView(d.bearings1, d.bearings2, InitOptions(gen));
  ASSERT_TRUE(r.ok()) << SolverStatusName(r.status) << ": " << r.message;
  EXPECT_EQ(r.model, TwoViewModel::kHomography) << "R_H = " << r.homography_ratio;
  EXPECT_GT(r.homography_ratio, 0.4);
  const SE3 gt = world_from_cam2.inverse();
  EXPECT_LT(test::RotationErrorDeg(r.cam2_from_cam1.rotation(), gt.rotation()), 0.5);
  EXPECT_LT(test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()), 2.0);
  EXPECT_GT(r.num_triangulated, 300);
  EXPECT_LT(MeanRelativePointError(r, d), 0.03);
}

// Noise equal to the assumed sigma: ORB-SLAM's original scoring put planes at
// R_H = 0.31-0.42 here (30 seeds); per-gate scoring keeps them at 0.44-0.57.
TEST(TwoViewInit, PlanarSceneWithNoiseAtSigmaStillChoosesHomography) {
  SceneGenerator gen(55);
  const SE3 world_from_cam2 = test::MakePose(4, -6, 2, Eigen::Vector3d(0.6, 0.1, 0.1));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 500, 1.0, 0.3, /*plane=*/true);
  const TwoViewInitResult r = InitializeTwoView(d.bearings1, d.bearings2, InitOptions(gen));
  ASSERT_TRUE(r.ok()) << SolverStatusName(r.status) << ": " << r.message;
  EXPECT_EQ(r.model, TwoViewModel::kHomography) << "R_H = " << r.homography_ratio;
  // Worst over 30 seeds: 0.69 deg rotation, 5.8 deg translation direction (planar
  // motion is weakly constrained at 1 px noise; not asserted beyond a sanity bound).
  const SE3 gt = world_from_cam2.inverse();
  EXPECT_LT(test::RotationErrorDeg(r.cam2_from_cam1.rotation(), gt.rotation()), 1.0);
  EXPECT_LT(test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()), 8.0);
}

TEST(TwoViewInit, GeneralSceneChoosesEssentialAndTriangulates) {
  SceneGenerator gen(53);
  const SE3 world_from_cam2 = test::MakePose(3, -8, 2, Eigen::Vector3d(0.6, 0.1, 0.15));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 500, 0.5, 0.3);
  const TwoViewInitResult r = InitializeTwoView(d.bearings1, d.bearings2, InitOptions(gen));
  ASSERT_TRUE(r.ok()) << SolverStatusName(r.status) << ": " << r.message;
  EXPECT_EQ(r.model, TwoViewModel::kEssential) << "R_H = " << r.homography_ratio;
  EXPECT_LT(r.homography_ratio, 0.3);
  const SE3 gt = world_from_cam2.inverse();
  EXPECT_LT(test::RotationErrorDeg(r.cam2_from_cam1.rotation(), gt.rotation()), 0.5);
  EXPECT_LT(test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()), 2.0);
  EXPECT_GT(r.median_parallax_deg, 1.0);
  EXPECT_GT(r.num_triangulated, 300);
  EXPECT_LT(MeanRelativePointError(r, d), 0.03);
  for (size_t i = 0; i < d.is_outlier.size(); ++i) {
    if (r.points_cam1[i]) {
      EXPECT_GT(r.points_cam1[i]->z(), 0.0);
    }
  }
}

// Driving forward (KITTI): most matches are distant points (buildings, horizon) whose rays
// stay parallel, a minority is near enough to triangulate. With count_distant_points the
// distant ones count towards the 90 % of inliers the motion must explain, as in ORB-SLAM;
// they do not become map points. Counting only triangulated points rejects this view.
TEST(TwoViewInit, ForwardMotionWithMostlyDistantPointsInitializes) {
  SceneGenerator gen(56);
  const SE3 world_from_cam2 = test::MakePose(0, -2, 0, Eigen::Vector3d(0.05, 0.0, 0.8));
  const SE3 cam2_from_world = world_from_cam2.inverse();
  test::TwoViewData d;
  d.world_from_cam2 = world_from_cam2;
  while (d.bearings1.size() < 500) {
    const bool distant = d.bearings1.size() % 5 < 3;  // 60 % at 300-2000 m
    const Eigen::Vector3d p = distant ? gen.PointInView(SE3(), 300.0, 2000.0) : gen.PointInView(SE3(), 4.0, 12.0);
    Eigen::Vector3d f1, f2;
    if (!gen.Observe(p, 0.5, &f1) || !gen.Observe(cam2_from_world * p, 0.5, &f2)) continue;
    d.points_world.push_back(p);
    d.bearings1.push_back(f1);
    d.bearings2.push_back(f2);
    d.is_outlier.push_back(false);
  }
  // Distant points fit the rotation's homography too (R_H 0.45 here): the VO's threshold.
  TwoViewInitOptions o = InitOptions(gen);
  o.min_homography_ratio = 0.7;
  const TwoViewInitResult strict = InitializeTwoView(d.bearings1, d.bearings2, o);
  EXPECT_EQ(strict.status, SolverStatus::kTooFewInliers) << strict.message;
  EXPECT_GT(strict.num_distant, strict.num_inliers / 3);
  o.count_distant_points = true;
  const TwoViewInitResult r = InitializeTwoView(d.bearings1, d.bearings2, o);
  ASSERT_TRUE(r.ok()) << SolverStatusName(r.status) << ": " << r.message;
  EXPECT_EQ(r.model, TwoViewModel::kEssential) << "R_H = " << r.homography_ratio;
  const SE3 gt = world_from_cam2.inverse();
  EXPECT_LT(test::RotationErrorDeg(r.cam2_from_cam1.rotation(), gt.rotation()), 0.5);
  EXPECT_LT(test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()), 3.0);
  EXPECT_GT(r.num_triangulated, 100);
  EXPECT_LT(r.num_triangulated, 0.6 * r.num_inliers);  // the distant majority is not in the map
  for (size_t i = 0; i < d.points_world.size(); ++i) {
    if (r.points_cam1[i]) {
      EXPECT_LT(d.points_world[i].norm(), 100.0) << "a distant point became a map point";
    }
  }
  EXPECT_LT(MeanRelativePointError(r, d), 0.05);
}

TEST(TwoViewInit, TinyBaselineIsRejectedForLowParallax) {
  SceneGenerator gen(54);
  const SE3 world_from_cam2 = test::MakePose(0, -1, 0, Eigen::Vector3d(0.03, 0, 0));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 400, 0.3, 0.1);
  const TwoViewInitResult r = InitializeTwoView(d.bearings1, d.bearings2, InitOptions(gen));
  EXPECT_FALSE(r.ok());
  EXPECT_TRUE(r.status == SolverStatus::kLowParallax || r.status == SolverStatus::kTooFewInliers)
      << SolverStatusName(r.status) << ": " << r.message;
}

// Short forward moves (8-15 cm at 3-9 m, 1 px noise, 360 views with and without a
// dominant plane) and 30 cm ones (60 views): the solver alone accepts motions whose
// translation points sideways (a small rotation explains the rest of the flow), the failure
// that distorted the VO's initial maps on generated halls (docs/vo.md).
struct ShortBaselineOutcome {
  int accepted_alone = 0, wrong_alone = 0, accepted_checked = 0, wrong_checked = 0;
  int long_accepted = 0, long_wrong = 0;
  double worst_checked_deg = 0.0;  // largest translation direction error the check accepted
};

ShortBaselineOutcome RunShortForwardBaselines(double min_homography_ratio,
                                              const std::function<void(TwoViewInitOptions*)>& enable_check,
                                              const std::function<void(const TwoViewInitResult&)>& on_refused) {
  ShortBaselineOutcome out;
  for (double tz : {0.08, 0.1, 0.12, 0.15, 0.3}) {
    for (bool plane : {false, true}) {
      if (tz > 0.2 && plane) continue;
      for (int seed = 0; seed < 60; ++seed) {
        SceneGenerator gen(1000 + seed);
        const SE3 world_from_cam2 = test::MakePose(0.2, 0.3, 0.1, Eigen::Vector3d(0.01, 0.01, tz));
        const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 300, 1.0, 0.1, plane);
        TwoViewInitOptions o = InitOptions(gen);
        o.min_homography_ratio = min_homography_ratio;
        const TwoViewInitResult alone = InitializeTwoView(d.bearings1, d.bearings2, o);
        enable_check(&o);
        const TwoViewInitResult checked = InitializeTwoView(d.bearings1, d.bearings2, o);
        const SE3 gt = world_from_cam2.inverse();
        auto wrong = [&](const TwoViewInitResult& r) {
          return test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()) > 30.0;
        };
        if (tz > 0.2) {
          out.long_accepted += checked.ok();
          out.long_wrong += checked.ok() && wrong(checked);
          continue;
        }
        out.accepted_alone += alone.ok();
        out.wrong_alone += alone.ok() && wrong(alone);
        out.accepted_checked += checked.ok();
        out.wrong_checked += checked.ok() && wrong(checked);
        if (checked.ok()) {
          out.worst_checked_deg = std::max(
              out.worst_checked_deg, test::DirectionErrorDeg(checked.cam2_from_cam1.translation(), gt.translation()));
        }
        if (alone.ok() && !checked.ok()) on_refused(checked);
      }
    }
  }
  std::printf("short forward baselines: alone %d accepted (%d wrong), checked %d accepted (%d wrong); 30 cm: %d/60\n",
              out.accepted_alone, out.wrong_alone, out.accepted_checked, out.wrong_checked, out.long_accepted);
  return out;
}

// Measured: 32 of 34 accepted motions were > 30 deg off. The rotation-residual check must
// refuse every one of them and none of the 30 cm views, which are all right.
TEST(TwoViewInit, AShortForwardBaselineIsRefusedInsteadOfMistakenForASidewaysMove) {
  const ShortBaselineOutcome r = RunShortForwardBaselines(
      0.4, [](TwoViewInitOptions* o) { o->min_rotation_residual_deg = 1.0; },
      [](const TwoViewInitResult& refused) {
        EXPECT_EQ(refused.status, SolverStatus::kLowParallax) << refused.message;
        EXPECT_LT(refused.rotation_residual_deg, 1.0);
      });
  EXPECT_GE(r.wrong_alone, 10) << "the short baselines no longer fool the solver alone: " << r.wrong_alone << " of "
                               << r.accepted_alone << " accepted motions wrong";
  EXPECT_EQ(r.wrong_checked, 0) << "of " << r.accepted_checked << " accepted";
  EXPECT_GE(r.long_accepted, 55) << "30 cm forward: the check refused good views";
  EXPECT_EQ(r.long_wrong, 0);
}

// The motion-cost gap (the VO's default) on the same views: a sideways motion that explains the
// view about as well as the chosen one refuses it, in units of the keypoint noise, so it
// does not depend on the camera's field of view as the rotation residual in degrees does.
TEST(TwoViewInit, AShortForwardBaselineWithARivalMotionIsRefusedByTheCostGap) {
  // At the VO's homography ratio (0.7): these views take the essential matrix there, and
  // only its motion is checked.
  const ShortBaselineOutcome r = RunShortForwardBaselines(
      0.7, [](TwoViewInitOptions* o) { o->min_motion_cost_gap = 30.0; },
      [](const TwoViewInitResult& refused) {
        EXPECT_EQ(refused.status, SolverStatus::kAmbiguous) << refused.message;
        EXPECT_LT(refused.motion_cost_gap, 30.0);
        EXPECT_GE(refused.rival_angle_deg, 30.0);
      });
  // Measured: alone 11 accepted, all > 30 deg off; checked 3 accepted, 32-37 deg off
  // (their rival, near the truth, trails by 32-41: the same broad valley, not a second
  // minimum). Gross errors like the halls' (73-99 deg) must all go.
  EXPECT_GE(r.wrong_alone, 8);
  EXPECT_LE(r.wrong_checked, 3) << "of " << r.accepted_checked << " accepted";
  EXPECT_LT(r.worst_checked_deg, 45.0);
  EXPECT_GE(r.long_accepted, 55) << "30 cm forward: the check refused good views";
  EXPECT_EQ(r.long_wrong, 0);
}

// On a plane every view has an epipolar rival (the other decomposition of its homography),
// so at the VO's homography ratio (0.7), where planar views take the essential matrix, the
// cost gap refuses most of them: this is why the VO stops refusing after
// init_max_ambiguous_attempts (VoOnAFloor in vo_sim_test). Counting the points the rival
// triangulates did not tell a plane's rival from a hall's true motion (both 0.2-0.9 of the
// chosen motion's), so the solver does not try.
TEST(TwoViewInit, APlaneAlwaysHasARivalMotion) {
  int accepted_alone = 0, refused_for_rival = 0;
  for (int seed = 0; seed < 30; ++seed) {
    for (double tx : {0.6, 0.3}) {
      SceneGenerator gen(50 + seed);
      const SE3 world_from_cam2 = test::MakePose(4, -6, 2, Eigen::Vector3d(tx, 0.1, 0.1));
      const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 500, 1.0, 0.3, /*plane=*/true);
      TwoViewInitOptions o = InitOptions(gen);
      o.min_homography_ratio = 0.7;
      const bool alone = InitializeTwoView(d.bearings1, d.bearings2, o).ok();
      accepted_alone += alone;
      o.min_motion_cost_gap = 30.0;
      const TwoViewInitResult r = InitializeTwoView(d.bearings1, d.bearings2, o);
      if (alone && !r.ok()) {
        EXPECT_EQ(r.status, SolverStatus::kAmbiguous) << r.message;
        EXPECT_GE(r.rival_angle_deg, 30.0);
        ++refused_for_rival;
      }
    }
  }
  std::printf("planes: %d of 60 initialize alone, %d of them refused for a rival motion\n", accepted_alone,
              refused_for_rival);
  EXPECT_GE(accepted_alone, 50);
  EXPECT_GE(refused_for_rival, accepted_alone / 2);
}

}  // namespace
}  // namespace ccm::solvers
