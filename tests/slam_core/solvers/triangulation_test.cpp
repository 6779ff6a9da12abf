#include <gtest/gtest.h>

#include "slam_core/solvers/triangulation.h"
#include "tests/slam_core/solvers/synthetic_scene.h"

namespace ccm::solvers {
namespace {

TriangulationOptions Options() {
  TriangulationOptions o;
  o.focal_px = 458.0;
  return o;
}

TEST(Triangulation, TwoViewRecoversPointsWithNoise) {
  test::SceneGenerator gen(41);
  const SE3 world_from_cam2 = test::MakePose(2, -6, 1, Eigen::Vector3d(0.5, 0.05, 0.1));
  const test::TwoViewData d = gen.MakeTwoView(world_from_cam2, 200, 0.5, 0.0);
  int ok = 0;
  double sum_rel = 0.0;
  for (size_t i = 0; i < d.bearings1.size(); ++i) {
    const TriangulationResult r = TriangulateTwoView(d.bearings1[i], d.bearings2[i], world_from_cam2.inverse(), Options());
    if (!r.ok()) continue;
    ++ok;
    sum_rel += (*r.point - d.points_world[i]).norm() / d.points_world[i].norm();
  }
  EXPECT_GT(ok, 190);
  EXPECT_LT(sum_rel / ok, 0.02);  // mean relative error with 0.5 px noise, 0.5 m baseline, 3-9 m
}

TEST(Triangulation, ExactBearingsGiveExactPointInBothApis) {
  const SE3 cam2_from_cam1 = test::MakePose(0, 5, 0, Eigen::Vector3d(-0.3, 0, 0));
  const Eigen::Vector3d p(0.4, -0.2, 4.0);
  const TriangulationResult r = TriangulateTwoView(p.normalized(), (cam2_from_cam1 * p).normalized(), cam2_from_cam1, Options());
  ASSERT_TRUE(r.ok());
  EXPECT_LT((*r.point - p).norm(), 1e-9);
  EXPECT_LT(r.max_error_px, 1e-6);
}

TEST(Triangulation, RejectsLowParallax) {
  const SE3 cam2_from_cam1(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.01, 0, 0));  // 1 cm baseline
  const Eigen::Vector3d p(0.1, 0.1, 5.0);
  const TriangulationResult r = TriangulateTwoView(p.normalized(), (cam2_from_cam1 * p).normalized(), cam2_from_cam1, Options());
  EXPECT_EQ(r.status, TriangulationStatus::kLowParallax);
  EXPECT_FALSE(r.point.has_value());
  EXPECT_GT(r.cos_parallax, 0.9998);
}

TEST(Triangulation, RejectsPointsBehindTheCamera) {
  const SE3 cam2_from_cam1(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.5, 0, 0));
  const Eigen::Vector3d p(0.3, 0.1, -4.0);  // behind both cameras: rays point away from it
  const TriangulationResult r =
      TriangulateTwoView(-p.normalized(), -(cam2_from_cam1 * p).normalized(), cam2_from_cam1, Options());
  EXPECT_EQ(r.status, TriangulationStatus::kBehindCamera);
  // Diverging rays (crossing behind cam1 only).
  const TriangulationResult r2 = TriangulateTwoView(Eigen::Vector3d(-0.2, 0, 1).normalized(),
                                                    Eigen::Vector3d(0.2, 0, 1).normalized(), cam2_from_cam1, Options());
  EXPECT_EQ(r2.status, TriangulationStatus::kBehindCamera);
}

TEST(Triangulation, RejectsInconsistentObservations) {
  const SE3 cam2_from_cam1(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.5, 0, 0));
  const Eigen::Vector3d p(0.3, 0.1, 4.0);
  // Second ray moved 10 px off the epipolar line (vertical, baseline is horizontal).
  Eigen::Vector3d f2 = cam2_from_cam1 * p;
  f2 = (f2 / f2.z() + Eigen::Vector3d(0, 10.0 / 458.0, 0)).normalized();
  const TriangulationResult r = TriangulateTwoView(p.normalized(), f2, cam2_from_cam1, Options());
  EXPECT_EQ(r.status, TriangulationStatus::kLargeError);
  EXPECT_GT(r.max_error_px, 3.0);
}

TEST(Triangulation, MultiViewUsesAllViewsAndChecksEach) {
  test::SceneGenerator gen(42);
  const Eigen::Vector3d p(0.5, -0.3, 6.0);
  std::vector<BearingObservation> views;
  for (int k = 0; k < 5; ++k) {
    const SE3 world_from_cam = test::MakePose(0, 3 * k, 0, Eigen::Vector3d(0.2 * k, 0.05 * k, 0));
    const SE3 cam_from_world = world_from_cam.inverse();
    Eigen::Vector3d f;
    ASSERT_TRUE(gen.Observe(cam_from_world * p, 0.3, &f));
    views.push_back({cam_from_world, f});
  }
  const TriangulationResult r = TriangulateMultiView(views, Options());
  ASSERT_TRUE(r.ok()) << TriangulationStatusName(r.status);
  EXPECT_LT((*r.point - p).norm(), 0.05);
  // One view 15 px off: the point still triangulates in front but that view's error is large.
  const Eigen::Vector3d f4 = views[4].bearing / views[4].bearing.z();
  views[4].bearing = (f4 + Eigen::Vector3d(0, 15.0 / 458.0, 0)).normalized();
  EXPECT_EQ(TriangulateMultiView(views, Options()).status, TriangulationStatus::kLargeError);
  EXPECT_EQ(TriangulateMultiView({views[0]}, Options()).status, TriangulationStatus::kInvalidInput);
}

}  // namespace
}  // namespace ccm::solvers
