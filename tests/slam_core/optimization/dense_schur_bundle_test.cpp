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

// Max pose translation / rotation and point distance between two solutions, and a cost check.
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
    dx = std::max(dx, (ours.problem.points[i].position_w - ceres.problem.points[i].position_w).norm());
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

}  // namespace
}  // namespace ccm::opt
