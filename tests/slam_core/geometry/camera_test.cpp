#include <gtest/gtest.h>

#include <random>

#include "slam_core/geometry/camera_models.h"

namespace ccm {
namespace {

CameraIntrinsics EurocCam0() {  // calibration of EuRoC MAV cam0
  CameraIntrinsics c;
  c.type = CameraType::kPinholeRadTan;
  c.width_px = 752;
  c.height_px = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return c;
}

CameraIntrinsics TumViFisheye() {  // calibration of a TUM-VI cam0 (equidistant)
  CameraIntrinsics c;
  c.type = CameraType::kFisheyeEquidistant;
  c.width_px = 512;
  c.height_px = 512;
  c.fx = 190.978;
  c.fy = 190.973;
  c.cx = 254.932;
  c.cy = 256.897;
  c.distortion = {0.0034823894, 0.000715034, -0.0020532361, 0.00020293673};
  return c;
}

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

TEST(Camera, PinholeRadTanRoundTripBelowMicroPixel) { CheckRoundTripOverImage(EurocCam0()); }
TEST(Camera, FisheyeRoundTripBelowMicroPixel) { CheckRoundTripOverImage(TumViFisheye(), 250.0); }

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

TEST(Camera, PinholeJacobianMatchesFiniteDifferences) { CheckJacobianNumerically(EurocCam0()); }
TEST(Camera, FisheyeJacobianMatchesFiniteDifferences) { CheckJacobianNumerically(TumViFisheye()); }

TEST(Camera, PointsBehindPinholeAreRejectedFisheyeSeesBeyondNinetyDegrees) {
  const auto pin = MakeCamera(EurocCam0());
  Eigen::Vector2d uv;
  EXPECT_FALSE(pin->Project({0.1, 0.1, -1.0}, &uv));
  EXPECT_FALSE(pin->Project({0.0, 0.0, 0.0}, &uv));
  const auto fish = MakeCamera(TumViFisheye());
  EXPECT_TRUE(fish->Project({1.0, 0.0, -0.05}, &uv));  // 93 deg off-axis
  EXPECT_FALSE(fish->Project({0.0, 0.0, -1.0}, &uv));  // straight behind
}

TEST(Camera, UndistortToNormalizedMatchesPinholeGeometry) {
  const auto cam = MakeCamera(EurocCam0());
  const Eigen::Vector3d p(0.4, -0.2, 2.0);
  Eigen::Vector2d uv, xy;
  ASSERT_TRUE(cam->Project(p, &uv));
  ASSERT_TRUE(cam->UnprojectToNormalized(uv, &xy));
  EXPECT_LT((xy - Eigen::Vector2d(0.2, -0.1)).norm(), 1e-10);
}

TEST(Camera, ValidationReportsWhatIsWrong) {
  CameraIntrinsics c = EurocCam0();
  EXPECT_EQ(ValidateIntrinsics(c), "");
  c.fx = 0;
  EXPECT_NE(ValidateIntrinsics(c).find("fx"), std::string::npos);
  EXPECT_EQ(MakeCamera(c), nullptr);
  c = TumViFisheye();
  c.distortion.push_back(0.1);
  EXPECT_NE(ValidateIntrinsics(c).find("4 distortion"), std::string::npos);
  c = EurocCam0();
  c.width_px = 0;
  EXPECT_NE(ValidateIntrinsics(c).find("image size"), std::string::npos);
}

}  // namespace
}  // namespace ccm
