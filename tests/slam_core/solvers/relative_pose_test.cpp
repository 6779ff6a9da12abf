#include <gtest/gtest.h>

#include "slam_core/solvers/relative_pose.h"
#include "tests/slam_core/solvers/synthetic_scene.h"

namespace ccm::solvers {
namespace {

using test::SceneGenerator;

struct MaskStats {
  double inliers_kept = 0, outliers_accepted = 0;
};

MaskStats CompareMask(const std::vector<bool>& mask, const std::vector<bool>& is_outlier) {
  int in = 0, in_kept = 0, out = 0, out_acc = 0;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (is_outlier[i]) {
      ++out;
      out_acc += mask[i];
    } else {
      ++in;
      in_kept += mask[i];
    }
  }
  return {double(in_kept) / std::max(in, 1), double(out_acc) / std::max(out, 1)};
}

RelativePoseOptions Options(const SceneGenerator& gen, RelativePoseAlgorithm algorithm) {
  RelativePoseOptions o;
  o.algorithm = algorithm;
  o.ransac.focal_px = gen.camera().intrinsics().fx;
  o.ransac.threshold_px = 2.0;
  o.ransac.max_iterations = 2000;
  return o;
}

class RelativePoseAlgorithms : public ::testing::TestWithParam<RelativePoseAlgorithm> {};

// 500 correspondences, 0.7 px noise, 40 % outliers, 0.6 m baseline at 3-9 m depth.
// Worst over 30 seeds (5pt): rotation 0.16 deg, translation direction 1.2 deg.
TEST_P(RelativePoseAlgorithms, RecoversKnownPoseWithNoiseAndOutliers) {
  SceneGenerator gen(11);
  const SE3 world_from_cam2 = test::MakePose(3, -8, 2, Eigen::Vector3d(0.6, 0.1, 0.15));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 500, 0.7, 0.4);
  const RelativePoseResult r = EstimateRelativePose(d.bearings1, d.bearings2, Options(gen, GetParam()));
  ASSERT_TRUE(r.ok()) << r.message;
  const SE3 gt = world_from_cam2.inverse();
  EXPECT_LT(test::RotationErrorDeg(r.cam2_from_cam1.rotation(), gt.rotation()), 0.5);
  EXPECT_LT(test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()), 2.0);
  EXPECT_NEAR(r.cam2_from_cam1.translation().norm(), 1.0, 1e-9);
  const MaskStats m = CompareMask(r.inliers, d.is_outlier);
  EXPECT_GT(m.inliers_kept, 0.95);
  EXPECT_LT(m.outliers_accepted, 0.05);
  EXPECT_EQ(r.num_inliers, std::count(r.inliers.begin(), r.inliers.end(), true));
}

INSTANTIATE_TEST_SUITE_P(AllSolvers, RelativePoseAlgorithms,
                         ::testing::Values(RelativePoseAlgorithm::kStewenius5pt, RelativePoseAlgorithm::kNister5pt,
                                           RelativePoseAlgorithm::kEightPoint));

TEST(RelativePose, WorksWithFisheyeBearings) {
  SceneGenerator gen(12, test::TumViLikeFisheye());
  const SE3 world_from_cam2 = test::MakePose(-5, 10, 4, Eigen::Vector3d(-0.5, 0.05, 0.3));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 400, 0.5, 0.3);
  const RelativePoseResult r = EstimateRelativePose(d.bearings1, d.bearings2,
                                                    Options(gen, RelativePoseAlgorithm::kStewenius5pt));
  ASSERT_TRUE(r.ok()) << r.message;
  const SE3 gt = world_from_cam2.inverse();
  EXPECT_LT(test::RotationErrorDeg(r.cam2_from_cam1.rotation(), gt.rotation()), 0.5);
  // f = 191 px: 0.5 px here is ~1.2 px at the EuRoC focal length, hence 3 deg
  // (worst over 30 seeds: 2.8 deg, mean 1.1 deg).
  EXPECT_LT(test::DirectionErrorDeg(r.cam2_from_cam1.translation(), gt.translation()), 3.0);
}

TEST(RelativePose, SameSeedGivesSameResult) {
  SceneGenerator gen(13);
  const test::TwoViewData d = gen.MakeTwoView(test::MakePose(0, 5, 0, Eigen::Vector3d(0.5, 0, 0)), 300, 1.0, 0.4);
  const RelativePoseOptions o = Options(gen, RelativePoseAlgorithm::kStewenius5pt);
  const RelativePoseResult a = EstimateRelativePose(d.bearings1, d.bearings2, o);
  const RelativePoseResult b = EstimateRelativePose(d.bearings1, d.bearings2, o);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.cam2_from_cam1.matrix(), b.cam2_from_cam1.matrix());
}

TEST(RelativePose, ReportsInvalidInputAndTooFewPoints) {
  SceneGenerator gen(14);
  const test::TwoViewData d = gen.MakeTwoView(test::MakePose(0, 0, 0, Eigen::Vector3d(0.5, 0, 0)), 10, 0.5, 0.0);
  RelativePoseOptions o = Options(gen, RelativePoseAlgorithm::kStewenius5pt);
  EXPECT_EQ(EstimateRelativePose(d.bearings1, d.bearings2, o).status, SolverStatus::kTooFewPoints);
  o.ransac.focal_px = 0.0;
  const RelativePoseResult bad = EstimateRelativePose(d.bearings1, d.bearings2, o);
  EXPECT_EQ(bad.status, SolverStatus::kInvalidInput);
  EXPECT_NE(bad.message.find("focal_px"), std::string::npos);
}

TEST(RelativePose, EssentialFromPoseSatisfiesEpipolarConstraint) {
  SceneGenerator gen(15);
  const SE3 world_from_cam2 = test::MakePose(10, -3, 7, Eigen::Vector3d(0.3, -0.2, 0.4));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 50, 0.0, 0.0);
  const Eigen::Matrix3d E = EssentialFromPose(world_from_cam2.inverse());
  for (size_t i = 0; i < d.bearings1.size(); ++i) EXPECT_NEAR(d.bearings2[i].dot(E * d.bearings1[i]), 0.0, 1e-9);
}

}  // namespace
}  // namespace ccm::solvers
