#include <gtest/gtest.h>

#include "slam_core/solvers/similarity.h"
#include "tests/slam_core/solvers/synthetic_scene.h"

namespace ccm::solvers {
namespace {

using test::SceneGenerator;

struct Sim3Data {
  Sim3 b_from_a;
  std::vector<Eigen::Vector3d> a, b;
  std::vector<bool> is_outlier;
};

// Points 2-10 m in front of camera a, mapped into camera b by a known Sim(3); each side
// gets noise equal to noise_px seen from its own camera (noise grows with depth, as for
// triangulated map points); outliers are matched to unrelated points.
Sim3Data MakeSim3(SceneGenerator* gen, int n, double noise_px, double outlier_ratio) {
  Sim3Data d;
  d.b_from_a = Sim3(2.3, Eigen::Quaterniond(test::MakePose(10, -25, 5, Eigen::Vector3d::Zero()).rotation()),
                    Eigen::Vector3d(0.4, -0.2, 0.9));
  const double f = gen->camera().intrinsics().fx;
  auto noisy = [&](const Eigen::Vector3d& p) {
    const double s = p.norm() * noise_px / f;
    return Eigen::Vector3d(p + Eigen::Vector3d(gen->Gaussian(s), gen->Gaussian(s), gen->Gaussian(s)));
  };
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d pa = gen->PointInView(SE3(), 2.0, 10.0);
    const bool outlier = gen->Uniform(0, 1) < outlier_ratio;
    const Eigen::Vector3d pb = d.b_from_a * (outlier ? gen->PointInView(SE3(), 2.0, 10.0) : pa);
    d.a.push_back(noisy(pa));
    d.b.push_back(noisy(pb));
    d.is_outlier.push_back(outlier);
  }
  return d;
}

Sim3Options Options(const SceneGenerator& gen, Sim3InlierMetric metric) {
  Sim3Options o;
  o.metric = metric;
  o.ransac.focal_px = gen.camera().intrinsics().fx;
  o.ransac.threshold_px = 4.0;  // isotropic 1 px noise on both sides: ~1.4 px angular error per axis
  o.max_relative_distance = 0.03;
  return o;
}

TEST(Umeyama, ExactDataGivesExactSim3AndCollinearIsRejected) {
  SceneGenerator gen(31);
  const Sim3Data d = MakeSim3(&gen, 20, 0.0, 0.0);
  const std::optional<Sim3> S = AlignUmeyama(d.a, d.b);
  ASSERT_TRUE(S.has_value());
  EXPECT_NEAR(S->scale(), 2.3, 1e-9);
  EXPECT_LT((S->matrix() - d.b_from_a.matrix()).norm(), 1e-9);
  const std::optional<Sim3> rigid = AlignUmeyama(d.a, d.b, /*fix_scale=*/true);
  ASSERT_TRUE(rigid.has_value());
  EXPECT_DOUBLE_EQ(rigid->scale(), 1.0);
  std::vector<Eigen::Vector3d> line = {{0, 0, 1}, {0, 0, 2}, {0, 0, 3}, {0, 0, 4}};
  EXPECT_FALSE(AlignUmeyama(line, line).has_value());
}

class Sim3Metrics : public ::testing::TestWithParam<Sim3InlierMetric> {};

// 300 correspondences, 1 px-equivalent noise, 40 % outliers, scale 2.3.
TEST_P(Sim3Metrics, RansacRecoversKnownSim3) {
  SceneGenerator gen(32);
  const Sim3Data d = MakeSim3(&gen, 300, 1.0, 0.4);
  const Sim3Result r = EstimateSim3(d.a, d.b, Options(gen, GetParam()));
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_NEAR(r.b_from_a.scale() / d.b_from_a.scale(), 1.0, 0.01);
  EXPECT_LT(test::RotationErrorDeg(r.b_from_a.rotation(), d.b_from_a.rotation()), 0.5);
  EXPECT_LT((r.b_from_a.translation() - d.b_from_a.translation()).norm(), 0.05);
  int accepted_outliers = 0, kept_inliers = 0, inliers = 0;
  for (size_t i = 0; i < d.is_outlier.size(); ++i) {
    accepted_outliers += d.is_outlier[i] && r.inliers[i];
    kept_inliers += !d.is_outlier[i] && r.inliers[i];
    inliers += !d.is_outlier[i];
  }
  EXPECT_LT(accepted_outliers, 5);
  EXPECT_GT(kept_inliers, 0.9 * inliers);
}

INSTANTIATE_TEST_SUITE_P(BothMetrics, Sim3Metrics,
                         ::testing::Values(Sim3InlierMetric::kAngular, Sim3InlierMetric::kRelativeDistance));

TEST(Sim3Ransac, DeterministicAndReportsFailures) {
  SceneGenerator gen(33);
  const Sim3Data d = MakeSim3(&gen, 100, 1.0, 0.5);
  const Sim3Options o = Options(gen, Sim3InlierMetric::kAngular);
  const Sim3Result a = EstimateSim3(d.a, d.b, o), b = EstimateSim3(d.a, d.b, o);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.b_from_a.matrix(), b.b_from_a.matrix());
  const std::vector<Eigen::Vector3d> two(d.a.begin(), d.a.begin() + 2);
  EXPECT_EQ(EstimateSim3(two, two, o).status, SolverStatus::kTooFewPoints);
  // Pure noise: no model gathers min_inliers.
  Sim3Data noise = MakeSim3(&gen, 100, 1.0, 1.0);
  Sim3Options strict = o;
  strict.min_inliers = 20;
  EXPECT_EQ(EstimateSim3(noise.a, noise.b, strict).status, SolverStatus::kTooFewInliers);
}

}  // namespace
}  // namespace ccm::solvers
