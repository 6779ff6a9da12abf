// The local BA's own dense-Schur Levenberg-Marquardt (BaLinearSolver::kAuto on small windows,
// dense_schur_bundle.h) against Ceres' DENSE_SCHUR (kDenseSchur) on the same problems: both
// converged tightly must reach the same minimum, with a fixed periphery, with the monocular
// scale gauge (one fixed pose: one translation component held), with and without the robust
// loss, and with fixed points.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "slam_core/optimization/bundle_adjustment.h"
#include "synthetic_scene.h"

namespace ccm::opt {
namespace {

struct Outcome {
  BundleProblem problem;
  OptimizationSummary summary;
};

Outcome Solve(BundleProblem p, BaLinearSolver solver, bool robust) {
  BundleAdjusterOptions o;
  o.linear_solver = solver;
  o.robust_iterations = robust ? 200 : 0;
  o.refine_iterations = robust ? 0 : 200;
  o.reject_outliers = false;
  o.function_tolerance = 1e-15;
  Outcome out{std::move(p), {}};
  out.summary = BundleAdjust(&out.problem, o);
  return out;
}

// Max pose translation / rotation and relative point distance between two solutions, and a cost check.
void ExpectSameMinimum(const Outcome& ours, const Outcome& ceres, const std::string& what) {
  ASSERT_TRUE(ours.summary.usable) << what << ": " << ours.summary.message;
  ASSERT_TRUE(ceres.summary.usable) << what << ": " << ceres.summary.message;
  double dt = 0.0, dr = 0.0, dx = 0.0;
  for (size_t i = 0; i < ours.problem.poses.size(); ++i) {
    const SE3& a = ours.problem.poses[i].world_from_cam;
    const SE3& b = ceres.problem.poses[i].world_from_cam;
    dt = std::max(dt, (a.translation() - b.translation()).norm());
    dr = std::max(dr, testing::RotationAngleDeg(a.rotation(), b.rotation()));
  }
  for (size_t i = 0; i < ours.problem.points.size(); ++i) {
    // Relative to the point's distance: a point 3 km out has a nearly free depth.
    const Eigen::Vector3d& x = ceres.problem.points[i].position_w;
    dx = std::max(dx, (ours.problem.points[i].position_w - x).norm() / (1.0 + x.norm()));
  }
  EXPECT_NEAR(ours.summary.final_cost, ceres.summary.final_cost, 1e-7 * ceres.summary.final_cost) << what;
  EXPECT_LT(ours.summary.final_cost, 0.1 * ours.summary.initial_cost) << what << ": the perturbation was undone";
  EXPECT_LT(dt, 1e-5) << what;
  EXPECT_LT(dr, 1e-4) << what;
  EXPECT_LT(dx, 1e-4) << what;
  std::printf("%s: cost %.9g vs %.9g, dt %.2g dr %.2g dx %.2g, iterations %d vs %d\n", what.c_str(),
              ours.summary.final_cost, ceres.summary.final_cost, dt, dr, dx, ours.summary.iterations,
              ceres.summary.iterations);
}

testing::Scene Window(std::uint32_t seed) {
  testing::SceneOptions so;
  so.num_keyframes = 24;
  so.num_points = 1500;
  so.pixel_noise_px = 1.0;
  so.max_pyramid_level = 3;
  so.seed = seed;
  return testing::MakeScene(so);
}

TEST(DenseSchurBundle, ReachesTheMinimumCeresReachesWithAFixedPeriphery) {
  testing::Scene scene = Window(5);
  BundleProblem& p = scene.problem;
  for (PoseBlock& pose : p.poses) pose.fixed = pose.id < 6 || pose.id >= 18;  // 12 free
  std::mt19937 rng(7);
  // A few gross outliers, so the robust pass has something to down-weight.
  for (size_t i = 0; i < p.observations.size(); i += 37) p.observations[i].uv_px += Eigen::Vector2d(25.0, -18.0);
  testing::Perturb(&p, 1.0, 0.05, 0.05, &rng);
  for (const bool robust : {true, false}) {
    const std::string what = robust ? "robust" : "plain";
    ExpectSameMinimum(Solve(p, BaLinearSolver::kAuto, robust), Solve(p, BaLinearSolver::kDenseSchur, robust), what);
  }
}

TEST(DenseSchurBundle, ReachesTheMinimumCeresReachesWithTheScaleGaugeAndFixedPoints) {
  testing::Scene scene = Window(9);
  BundleProblem& p = scene.problem;
  for (PoseBlock& pose : p.poses) pose.fixed = pose.id == 0;  // one fixed pose: the scale gauge holds
  std::mt19937 rng(3);
  testing::Perturb(&p, 0.5, 0.03, 0.03, &rng);
  // Without the held component the map could scale about the fixed pose, and the two solvers
  // would stop at different scales of the same minimum.
  ExpectSameMinimum(Solve(p, BaLinearSolver::kAuto, true), Solve(p, BaLinearSolver::kDenseSchur, true), "gauge");
  for (size_t i = 0; i < p.points.size(); i += 5) p.points[i].fixed = true;  // now points fix the scale
  ExpectSameMinimum(Solve(p, BaLinearSolver::kAuto, false), Solve(p, BaLinearSolver::kDenseSchur, false), "fixed points");
}

// A window whose blocks span many orders of magnitude: far points and points of gross
// outliers only (tiny blocks) beside points a few centimetres in front of a camera (huge
// ones), as an agent's local BA meets after a bad triangulation. Unscaled, a tiny point block
// failed the inversion's determinant check and every step was rejected (seen on the
// repeated-objects scene: the VO then lost track); with Ceres' Jacobi scaling both solvers
// reach the same minimum, and the same cost in the agent's 5 + 10 iterations.
TEST(DenseSchurBundle, ReachesTheMinimumCeresReachesWithFarAndNearPoints) {
  testing::Scene scene = Window(13);
  BundleProblem& p = scene.problem;
  for (PoseBlock& pose : p.poses) pose.fixed = pose.id < 4 || pose.id >= 16;
  const CameraModel& camera = *p.cameras[0];
  std::mt19937 rng(17);
  std::normal_distribution<double> noise(0.0, 1.0);
  const int first_new = static_cast<int>(p.points.size());
  for (int k = 0; k < 60; ++k) {
    // 40 points 300-3000 m out along keyframe 8's view, 20 points 3-8 cm in front of keyframe 10.
    const bool far = k < 40;
    const SE3& from = p.poses[far ? 8 : 10].world_from_cam;
    const double depth = far ? 300.0 * std::pow(10.0, (k % 10) / 9.0) : 0.03 + 0.0025 * (k - 40);
    const Eigen::Vector3d ray((k % 7 - 3) * 0.05, (k % 5 - 2) * 0.05, 1.0);
    p.points.push_back(PointBlock{static_cast<std::uint64_t>(100000 + k), from * (depth * ray), false, -1});
  }
  for (int i = first_new; i < static_cast<int>(p.points.size()); ++i) {
    for (int pose = 0; pose < static_cast<int>(p.poses.size()); ++pose) {
      const Eigen::Vector3d p_cam = p.poses[pose].world_from_cam.inverse() * p.points[i].position_w;
      Eigen::Vector2d uv;
      if (p_cam.z() < 0.01 || !camera.Project(p_cam, &uv) || !camera.InImage(uv)) continue;
      p.observations.push_back(Observation{pose, i, uv + Eigen::Vector2d(noise(rng), noise(rng)), 1.0});
    }
  }
  // Points measured with very little weight (a Huber weight of 1e-6 after a gross error has
  // the same effect): their 3x3 blocks have determinants of ~1e-15.
  for (Observation& o : p.observations) {
    if (o.point_index % 300 == 11) o.sigma_px = 1000.0;
  }
  testing::Perturb(&p, 0.3, 0.02, 0.02, &rng);
  for (const bool robust : {true, false}) {
    ExpectSameMinimum(Solve(p, BaLinearSolver::kAuto, robust), Solve(p, BaLinearSolver::kDenseSchur, robust),
                      robust ? "far and near, robust" : "far and near, plain");
  }
  // Then a few points whose every observation is a gross outlier (1e6 px off: a point
  // triangulated through a camera centre): their Huber weights are ~1e-6, so their blocks
  // too. As the agent runs it (5 robust iterations, outliers out, 10 plain ones) the solver
  // must get as far as Ceres.
  int gross = 0;
  for (size_t i = 0; i < p.observations.size(); ++i) {
    if (p.observations[i].point_index % 500 != 7) continue;
    p.observations[i].uv_px += Eigen::Vector2d(1e6, -1e6);
    ++gross;
  }
  ASSERT_GT(gross, 5);
  BundleAdjusterOptions o = LocalBaDefaults();
  BundleProblem ours = p, ceres = p;
  const OptimizationSummary so = BundleAdjust(&ours, o);
  o.linear_solver = BaLinearSolver::kDenseSchur;
  const OptimizationSummary sc = BundleAdjust(&ceres, o);
  ASSERT_TRUE(so.usable && sc.usable);
  std::printf("local BA defaults: %.6g -> %.6g (%d it, %d rejected) vs Ceres %.6g (%d it, %d rejected)\n",
              so.initial_cost, so.final_cost, so.iterations, so.rejected_steps, sc.final_cost, sc.iterations,
              sc.rejected_steps);
  EXPECT_LT(so.final_cost, 1.05 * sc.final_cost);
  EXPECT_LT(so.final_cost, 0.1 * so.initial_cost);
}

}  // namespace
}  // namespace ccm::opt
