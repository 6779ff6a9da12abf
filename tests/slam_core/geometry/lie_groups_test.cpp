#include <gtest/gtest.h>

#include <random>

#include "slam_core/geometry/se3.h"
#include "slam_core/geometry/sim3.h"

namespace ccm {
namespace {

Eigen::Matrix<double, 6, 1> RandomTwist(std::mt19937& rng, double rot_scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix<double, 6, 1> xi;
  for (int i = 0; i < 3; ++i) xi(i) = n(rng);
  for (int i = 3; i < 6; ++i) xi(i) = rot_scale * n(rng);
  return xi;
}

TEST(SE3, ExpLogRoundTripAllAngleRanges) {
  std::mt19937 rng(1);
  for (double rot_scale : {1e-9, 1e-6, 1e-3, 0.3, 1.5}) {
    for (int k = 0; k < 50; ++k) {
      Eigen::Matrix<double, 6, 1> xi = RandomTwist(rng, rot_scale);
      if (xi.tail<3>().norm() > 3.0) continue;  // keep within (-pi, pi)
      const Eigen::Matrix<double, 6, 1> back = SE3::Exp(xi).Log();
      EXPECT_LT((back - xi).norm(), 1e-9) << "rot_scale " << rot_scale;
    }
  }
}

TEST(SE3, ExpMatchesMatrixExponentialForPureTranslationAndRotation) {
  Eigen::Matrix<double, 6, 1> xi = Eigen::Matrix<double, 6, 1>::Zero();
  xi.head<3>() << 1, 2, 3;
  EXPECT_LT((SE3::Exp(xi).translation() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  xi.setZero();
  xi(5) = M_PI / 2;  // 90 deg about z
  const Eigen::Vector3d p = SE3::Exp(xi) * Eigen::Vector3d(1, 0, 0);
  EXPECT_LT((p - Eigen::Vector3d(0, 1, 0)).norm(), 1e-12);
}

TEST(SE3, CompositionInverseAndMatrixAgree) {
  std::mt19937 rng(2);
  const SE3 a = SE3::Exp(RandomTwist(rng, 0.5)), b = SE3::Exp(RandomTwist(rng, 0.5));
  const Eigen::Vector3d p(0.3, -1.2, 4.0);
  EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-12);
  EXPECT_LT(((a * a.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  EXPECT_LT(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 1e-12);
}

TEST(SE3, InterpolateHitsEndpointsAndMidpointIsHalfwayOnGeodesic) {
  std::mt19937 rng(3);
  const SE3 a = SE3::Exp(RandomTwist(rng, 0.5)), b = SE3::Exp(RandomTwist(rng, 0.5));
  EXPECT_LT((SE3::Interpolate(a, b, 0.0).matrix() - a.matrix()).norm(), 1e-12);
  EXPECT_LT((SE3::Interpolate(a, b, 1.0).matrix() - b.matrix()).norm(), 1e-9);
  const SE3 m = SE3::Interpolate(a, b, 0.5);
  const SE3 a_to_m = a.inverse() * m, m_to_b = m.inverse() * b;
  EXPECT_LT((a_to_m.Log() - m_to_b.Log()).norm(), 1e-9);
}

TEST(Sim3, ExpLogRoundTripIncludingSmallScaleAndAngle) {
  std::mt19937 rng(4);
  std::normal_distribution<double> n(0.0, 1.0);
  for (double rot_scale : {1e-9, 1e-4, 0.5}) {
    for (double sig_scale : {0.0, 1e-8, 0.3}) {
      for (int k = 0; k < 20; ++k) {
        Eigen::Matrix<double, 7, 1> xi;
        xi.head<6>() = RandomTwist(rng, rot_scale);
        xi(6) = sig_scale * n(rng);
        if (xi.segment<3>(3).norm() > 3.0) continue;
        EXPECT_LT((Sim3::Exp(xi).Log() - xi).norm(), 1e-8);
      }
    }
  }
}

TEST(Sim3, ExpWithZeroScaleEqualsSE3Exp) {
  std::mt19937 rng(5);
  Eigen::Matrix<double, 7, 1> xi;
  xi.head<6>() = RandomTwist(rng, 0.7);
  xi(6) = 0;
  const Sim3 s = Sim3::Exp(xi);
  const SE3 t = SE3::Exp(xi.head<6>());
  EXPECT_NEAR(s.scale(), 1.0, 1e-15);
  EXPECT_LT((s.matrix() - t.matrix()).norm(), 1e-10);
}

TEST(Sim3, ActionCompositionInverse) {
  const Sim3 a(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized())),
               Eigen::Vector3d(1, -1, 0.5));
  const Sim3 b(0.7, Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0, 2, 1));
  const Eigen::Vector3d p(1.0, 2.0, -3.0);
  EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-12);
  EXPECT_LT((a.inverse() * (a * p) - p).norm(), 1e-12);
  EXPECT_LT(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 1e-12);
  // TransformPose keeps the pose rigid and maps the camera centre.
  const SE3 pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())), Eigen::Vector3d(3, 0, 1));
  const SE3 moved = a.TransformPose(pose);
  EXPECT_LT((moved.translation() - a * pose.translation()).norm(), 1e-12);
  EXPECT_NEAR(moved.rotation().norm(), 1.0, 1e-12);
}

}  // namespace
}  // namespace ccm
