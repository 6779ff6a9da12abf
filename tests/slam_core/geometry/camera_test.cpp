#include <gtest/gtest.h>

#include <random>

#include "slam_core/geometry/camera_models.h"
#include "slam_core/geometry/camera_presets.h"

namespace ccm {
namespace {

// max_radius_px: fisheye image corners lie beyond the lens' field of view (black in
// real images), so only the image circle is checked there.
void CheckRoundTripOverImage(const CameraIntrinsics& c, double max_radius_px = 1e9) {
  const auto cam = MakeCamera(c);
  ASSERT_TRUE(cam);
  double worst = 0;
  int tested = 0;
  for (double v = 0; v < c.height_px; v += 7.3) {
    for (double u = 0; u < c.width_px; u += 7.3) {
      if (std::hypot(u - c.cx, v - c.cy) > max_radius_px) continue;
      Eigen::Vector3d bearing;
      ASSERT_TRUE(cam->Unproject({u, v}, &bearing)) << u << "," << v;
      EXPECT_NEAR(bearing.norm(), 1.0, 1e-12);
      Eigen::Vector2d uv;
      ASSERT_TRUE(cam->Project(3.7 * bearing, &uv));
      worst = std::max(worst, (uv - Eigen::Vector2d(u, v)).norm());
      ++tested;
    }
  }
  EXPECT_GT(tested, 1000);
  EXPECT_LT(worst, 1e-6) << CameraTypeName(c.type);
}

TEST(Camera, PinholeRadTanRoundTripBelowMicroPixel) { CheckRoundTripOverImage(EurocCam0Intrinsics()); }
TEST(Camera, FisheyeRoundTripBelowMicroPixel) { CheckRoundTripOverImage(TumViFisheyeIntrinsics(), 250.0); }

void CheckJacobianNumerically(const CameraIntrinsics& c) {
  const auto cam = MakeCamera(c);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d p(u(rng), 0.6 * u(rng), 1.5 + u(rng));
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 3> j;
    if (!cam->Project(p, &uv, &j)) continue;
    for (int a = 0; a < 3; ++a) {
      const double h = 1e-6;
      Eigen::Vector3d dp = Eigen::Vector3d::Zero();
      dp(a) = h;
      Eigen::Vector2d up, um;
      ASSERT_TRUE(cam->Project(p + dp, &up));
      ASSERT_TRUE(cam->Project(p - dp, &um));
      const Eigen::Vector2d numeric = (up - um) / (2 * h);
      EXPECT_LT((numeric - j.col(a)).norm(), 1e-4 * (1.0 + j.col(a).norm()));
    }
  }
}

TEST(Camera, PinholeJacobianMatchesFiniteDifferences) { CheckJacobianNumerically(EurocCam0Intrinsics()); }
TEST(Camera, FisheyeJacobianMatchesFiniteDifferences) { CheckJacobianNumerically(TumViFisheyeIntrinsics()); }

TEST(Camera, PointsBehindPinholeAreRejectedFisheyeSeesBeyondNinetyDegrees) {
  const auto pin = MakeCamera(EurocCam0Intrinsics());
  Eigen::Vector2d uv;
  EXPECT_FALSE(pin->Project({0.1, 0.1, -1.0}, &uv));
  EXPECT_FALSE(pin->Project({0.0, 0.0, 0.0}, &uv));
  const auto fish = MakeCamera(TumViFisheyeIntrinsics());
  EXPECT_TRUE(fish->Project({1.0, 0.0, -0.05}, &uv));  // 93 deg off-axis
  EXPECT_FALSE(fish->Project({0.0, 0.0, -1.0}, &uv));  // straight behind
}

// Costs must not fail where Project says "not visible" only because the distortion model
// folds over there: ProjectForCost gives Project's pixel and Jacobian where Project works and
// continues smoothly past the fold; behind a pinhole it still fails.
TEST(Camera, ProjectForCostContinuesPastTheFold) {
  CameraIntrinsics wide;
  wide.width_px = 848;
  wide.height_px = 480;
  wide.fx = wide.fy = 350;
  wide.cx = 424;
  wide.cy = 240;
  wide.distortion = {-0.2, 0.0, 0.0, 0.0};  // radial fold at r = sqrt(1 / 0.6) = 1.291
  const auto pin = MakeCamera(wide);
  Eigen::Vector2d uv, uv_cost;
  Eigen::Matrix<double, 2, 3> j, j_cost;
  ASSERT_TRUE(pin->Project({1.2, 0.3, 1.0}, &uv, &j));
  ASSERT_TRUE(pin->ProjectForCost({1.2, 0.3, 1.0}, &uv_cost, &j_cost));
  EXPECT_EQ(uv, uv_cost);
  EXPECT_EQ(j, j_cost);
  const Eigen::Vector3d past(1.35, 0.0, 1.0);
  EXPECT_FALSE(pin->Project(past, &uv));
  ASSERT_TRUE(pin->ProjectForCost(past, &uv_cost, &j_cost));
  Eigen::Vector2d at_fold;
  ASSERT_TRUE(pin->Project({1.29, 0.0, 1.0}, &at_fold));
  EXPECT_LT(uv_cost.x(), at_fold.x()) << "past the fold the polynomial turns back towards the centre";
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d h = 1e-6 * Eigen::Vector3d::Unit(a);
    Eigen::Vector2d up, um;
    ASSERT_TRUE(pin->ProjectForCost(past + h, &up));
    ASSERT_TRUE(pin->ProjectForCost(past - h, &um));
    EXPECT_LT(((up - um) / 2e-6 - j_cost.col(a)).norm(), 1e-4 * (1.0 + j_cost.col(a).norm()));
  }
  EXPECT_FALSE(pin->ProjectForCost({0.1, 0.1, -1.0}, &uv));

  const FisheyeEquidistantCamera fish(TumViFisheyeIntrinsics());
  const double beyond = fish.max_theta_rad() + 0.05;
  const Eigen::Vector3d ray(std::sin(beyond), 0.0, std::cos(beyond));
  EXPECT_FALSE(fish.Project(ray, &uv));
  EXPECT_TRUE(fish.ProjectForCost(ray, &uv));
  EXPECT_FALSE(fish.ProjectForCost({0.0, 0.0, -1.0}, &uv));  // straight behind: no pixel
}

TEST(Camera, UndistortToNormalizedMatchesPinholeGeometry) {
  const auto cam = MakeCamera(EurocCam0Intrinsics());
  const Eigen::Vector3d p(0.4, -0.2, 2.0);
  Eigen::Vector2d uv, xy;
  ASSERT_TRUE(cam->Project(p, &uv));
  ASSERT_TRUE(cam->UnprojectToNormalized(uv, &xy));
  EXPECT_LT((xy - Eigen::Vector2d(0.2, -0.1)).norm(), 1e-10);
}

TEST(Camera, ValidationReportsWhatIsWrong) {
  CameraIntrinsics c = EurocCam0Intrinsics();
  EXPECT_EQ(ValidateIntrinsics(c), "");
  c.fx = 0;
  EXPECT_NE(ValidateIntrinsics(c).find("fx"), std::string::npos);
  EXPECT_EQ(MakeCamera(c), nullptr);
  c = TumViFisheyeIntrinsics();
  c.distortion.push_back(0.1);
  EXPECT_NE(ValidateIntrinsics(c).find("4 distortion"), std::string::npos);
  c = EurocCam0Intrinsics();
  c.width_px = 0;
  EXPECT_NE(ValidateIntrinsics(c).find("image size"), std::string::npos);
}

}  // namespace
}  // namespace ccm
