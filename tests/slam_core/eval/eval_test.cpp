#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "slam_core/eval/evaluator.h"

namespace ccm {
namespace {

Eigen::Quaterniond RandomRotation(std::mt19937* rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Quaterniond(Eigen::Vector4d(g(*rng), g(*rng), g(*rng), g(*rng))).normalized();
}

Sim3 RandomSim3(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::uniform_real_distribution<double> log_s(std::log(0.1), std::log(10.0));
  return Sim3(std::exp(log_s(*rng)), RandomRotation(rng), Eigen::Vector3d(u(*rng), u(*rng), u(*rng)));
}

// A drone-like 3D path: a wobbly loop with altitude change, yaw following the motion.
Trajectory LoopTrajectory(int n, int64_t start_ns, double radius, double phase) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double a = phase + 2.0 * M_PI * i / n;
    const Eigen::Vector3d p(radius * std::cos(a), 0.6 * radius * std::sin(a), 1.0 + 0.3 * std::sin(3 * a));
    const Eigen::Quaterniond q(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.2 * std::sin(2 * a), Eigen::Vector3d::UnitX()));
    t.push_back(StampedPose{start_ns + i * 50000000LL, SE3(q, p)});
  }
  return t;
}

// The estimate a SLAM system would give: est_from_gt applied to every pose.
Trajectory Transform(const Trajectory& gt, const Sim3& est_from_gt) {
  Trajectory est = gt;
  for (StampedPose& p : est) p.world_from_cam = est_from_gt.TransformPose(p.world_from_cam);
  return est;
}

void ExpectSim3Near(const Sim3& a, const Sim3& b, double tol) {
  EXPECT_NEAR(a.scale(), b.scale(), tol);
  EXPECT_LT(a.rotation().angularDistance(b.rotation()), tol);
  EXPECT_LT((a.translation() - b.translation()).norm(), tol * 10);
}

TEST(Umeyama, RecoversRandomSim3AndSe3) {
  std::mt19937 rng(42);
  std::normal_distribution<double> g(0.0, 2.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Sim3 gt_from_est = RandomSim3(&rng);
    std::vector<Eigen::Vector3d> est, gt;
    for (int i = 0; i < 50; ++i) {
      est.emplace_back(g(rng), g(rng), g(rng));
      gt.push_back(gt_from_est * est.back());
    }
    std::string error;
    const std::optional<Sim3> sim3 = UmeyamaAlignment(est, gt, true, &error);
    ASSERT_TRUE(sim3) << error;
    ExpectSim3Near(*sim3, gt_from_est, 1e-9);
    const Sim3 rigid(1.0, gt_from_est.rotation(), gt_from_est.translation());
    for (size_t i = 0; i < est.size(); ++i) gt[i] = rigid * est[i];
    const std::optional<Sim3> se3 = UmeyamaAlignment(est, gt, false, &error);
    ASSERT_TRUE(se3) << error;
    ExpectSim3Near(*se3, rigid, 1e-9);
  }
}

TEST(Umeyama, PlanarPointsStillGiveAProperRotation) {
  // Rank-2 covariance (a ground robot or a level flight): the third axis comes from the
  // determinant condition, never a reflection.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  const Sim3 gt_from_est = RandomSim3(&rng);
  std::vector<Eigen::Vector3d> est, gt;
  for (int i = 0; i < 30; ++i) {
    est.emplace_back(u(rng), u(rng), 0.0);
    gt.push_back(gt_from_est * est.back());
  }
  std::string error;
  const std::optional<Sim3> sim3 = UmeyamaAlignment(est, gt, true, &error);
  ASSERT_TRUE(sim3) << error;
  ExpectSim3Near(*sim3, gt_from_est, 1e-9);
  EXPECT_GT(sim3->rotation_matrix().determinant(), 0.0);
}

TEST(Umeyama, RejectsTooFewAndCollinearPoints) {
  std::string error;
  std::vector<Eigen::Vector3d> two = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0)};
  EXPECT_FALSE(UmeyamaAlignment(two, two, true, &error));
  EXPECT_NE(error.find(">= 3"), std::string::npos);
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(i, 2.0 * i, 0.0);
  EXPECT_FALSE(UmeyamaAlignment(line, line, true, &error));
  EXPECT_NE(error.find("degenerate"), std::string::npos);
}

TEST(Ate, SelfUnderRandomSim3IsZeroAfterAlignment) {
  std::mt19937 rng(7);
  const Trajectory gt = LoopTrajectory(400, 1000000000LL, 5.0, 0.0);
  const Sim3 est_from_gt = RandomSim3(&rng);
  EvalReport report;
  std::string error;
  ASSERT_TRUE(Evaluate({{"a", gt, Transform(gt, est_from_gt)}}, EvalOptions(), &report, &error)) << error;
  const AgentResult& a = report.agents[0];
  EXPECT_EQ(a.matched, 400u);
  EXPECT_LT(a.ate_m.max, 1e-9);
  EXPECT_LT(a.rpe.translation_m.max, 1e-9);
  EXPECT_LT(a.rpe.rotation_deg.max, 1e-6);
  ExpectSim3Near(a.gt_from_est, est_from_gt.inverse(), 1e-9);

  EvalOptions se3;
  se3.alignment = AlignmentType::kSE3;  // wrong model for a scaled estimate: error stays
  ASSERT_TRUE(Evaluate({{"a", gt, Transform(gt, est_from_gt)}}, se3, &report, &error));
  EXPECT_GT(report.agents[0].ate_m.rmse, 0.01);
}

TEST(Ate, EqualsInjectedNoiseRmse) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.05);
  const Trajectory gt = LoopTrajectory(2000, 0, 8.0, 0.3);
  const Sim3 est_from_gt = RandomSim3(&rng);
  Trajectory noisy = gt;
  double sse = 0;
  for (StampedPose& p : noisy) {
    const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
    sse += n.squaredNorm();
    p.world_from_cam = SE3(p.world_from_cam.rotation(), p.world_from_cam.translation() + n);
  }
  const double injected_rmse = std::sqrt(sse / gt.size());
  EvalReport report;
  std::string error;
  ASSERT_TRUE(Evaluate({{"a", gt, Transform(noisy, est_from_gt)}}, EvalOptions(), &report, &error));
  // The alignment absorbs a little of the noise (7 dof of 6000): a few % at most.
  EXPECT_NEAR(report.agents[0].ate_m.rmse, injected_rmse, 0.03 * injected_rmse);
  EXPECT_LT(report.agents[0].ate_m.rmse, injected_rmse);
}

TEST(Stats, MatchNumpyConventions) {
  const ErrorStats s = ComputeStats({1.0, 2.0, 3.0, 4.0});
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population std (numpy.std)
  EXPECT_DOUBLE_EQ(s.sse, 30.0);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_EQ(ComputeStats({}).count, 0u);
}

TEST(Association, NearestWithinToleranceAndOffset) {
  Trajectory gt, est;
  for (int i = 0; i < 100; ++i) gt.push_back({i * 10000000LL, SE3()});   // 100 Hz
  for (int i = 0; i < 20; ++i) est.push_back({i * 50000000LL + 3000000LL, SE3()});  // 20 Hz, +3 ms
  AssociationOptions options;
  options.max_dt_s = 0.004;
  std::vector<AssociatedPair> pairs = AssociateByStamp(gt, est, options);
  ASSERT_EQ(pairs.size(), 20u);
  EXPECT_EQ(pairs[4].est_index, 4u);
  EXPECT_EQ(pairs[4].gt_index, 20u);  // 203 ms -> 200 ms
  options.max_dt_s = 0.002;
  EXPECT_TRUE(AssociateByStamp(gt, est, options).empty());
  options.est_offset_s = -0.003;  // shifts the estimate back onto the grid
  options.max_dt_s = 0.0;
  EXPECT_EQ(AssociateByStamp(gt, est, options).size(), 20u);
  // Longer estimate than ground truth: iteration runs over the ground truth instead.
  options = AssociationOptions();
  pairs = AssociateByStamp(est, gt, options);
  ASSERT_EQ(pairs.size(), 20u);
  EXPECT_EQ(pairs[4].gt_index, 4u);
  EXPECT_EQ(pairs[4].est_index, 20u);
}

TEST(Joint, OneAlignmentForAllAgents) {
  std::mt19937 rng(5);
  const Trajectory gt_a = LoopTrajectory(300, 0, 4.0, 0.0);
  const Trajectory gt_b = LoopTrajectory(300, 0, 6.0, 1.0);
  const Sim3 map_from_world = RandomSim3(&rng);
  // Both agents in one map frame: joint ATE ~ 0.
  std::vector<AgentInput> agents = {{"a", gt_a, Transform(gt_a, map_from_world)},
                                    {"b", gt_b, Transform(gt_b, map_from_world)}};
  EvalReport report;
  std::string error;
  ASSERT_TRUE(Evaluate(agents, EvalOptions(), &report, &error)) << error;
  EXPECT_EQ(report.joint.matched, 600u);
  EXPECT_LT(report.joint.ate_m.max, 1e-9);
  ExpectSim3Near(report.joint.gt_from_est, map_from_world.inverse(), 1e-9);

  // Agent b's map is offset by 1 m (a failed merge): each alone still aligns perfectly, the
  // joint alignment cannot, and its error is what the collaborative RMSE must show.
  const Sim3 offset(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 0.0, 0.0));
  agents[1].est = Transform(gt_b, offset * map_from_world);
  ASSERT_TRUE(Evaluate(agents, EvalOptions(), &report, &error)) << error;
  EXPECT_LT(report.agents[0].ate_m.max, 1e-9);
  EXPECT_LT(report.agents[1].ate_m.max, 1e-9);
  EXPECT_GT(report.joint.ate_m.rmse, 0.1);
  EXPECT_GT(report.agents[0].ate_joint_m.rmse, 0.05);
  EXPECT_EQ(report.joint.ate_m.count, 600u);
}

TEST(Rpe, PairsAndKnownDrift) {
  // Straight line along x at 0.1 m per frame; the estimate moves 0.11 m per frame and rolls
  // (about x, the motion direction) 0.5 deg per frame more than the truth.
  Trajectory gt, est;
  for (int i = 0; i < 101; ++i) {
    gt.push_back({i * 100000000LL, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1 * i, 0, 0))});
    const Eigen::Quaterniond yaw(Eigen::AngleAxisd(0.5 * i * M_PI / 180.0, Eigen::Vector3d::UnitX()));
    est.push_back({i * 100000000LL, SE3(yaw, Eigen::Vector3d(0.11 * i, 0, 0))});
  }
  std::vector<SE3> g, e;
  for (size_t i = 0; i < gt.size(); ++i) g.push_back(gt[i].world_from_cam), e.push_back(est[i].world_from_cam);
  RpeOptions options;
  options.delta = 10;
  RpeResult rpe = ComputeRpe(g, e, options);
  ASSERT_EQ(rpe.pairs.size(), 10u);  // (0,10), (10,20), ... (90,100): evo's non-overlapping pairs
  EXPECT_EQ(rpe.pairs[1], std::make_pair(size_t{10}, size_t{20}));
  EXPECT_NEAR(rpe.rotation_deg.mean, 5.0, 1e-9);
  // est_i^-1 est_j moves 1.1 m along x (a roll keeps x), gt 1.0 m.
  EXPECT_NEAR(rpe.translation_m.min, 0.1, 1e-9);
  EXPECT_NEAR(rpe.translation_m.max, 0.1, 1e-9);
  options.all_pairs = true;
  EXPECT_EQ(RpePairs(g, options).size(), 91u);
  options = RpeOptions();
  options.unit = RpeDeltaUnit::kMeters;
  options.delta = 1.95;  // 0.1 m steps: every 20th frame
  const auto by_path = RpePairs(g, options);
  ASSERT_FALSE(by_path.empty());
  EXPECT_EQ(by_path[0].second - by_path[0].first, 20u);
  ASSERT_EQ(by_path.size(), 4u);  // ids 20, 40, 60, 80, 100 (evo starts at the first crossing)
  options.all_pairs = true;
  options.delta = 2.05;  // within 10%: j = i + 20 for i <= 80, and i = 81 (1.9 m)
  EXPECT_EQ(RpePairs(g, options).size(), 82u);
  std::string error;
  options.unit = RpeDeltaUnit::kFrames;
  options.delta = 1.5;
  EXPECT_FALSE(options.Validate(&error));
}

// A monocular estimate whose scale shrinks steadily: each step of the loop is drawn 1.0x at
// the start and 0.7x at the end. The ATE after one Sim(3) mixes this with everything else;
// the scale drift names it: first windows above the last by ~1/0.7.
TEST(ScaleDriftMetric, SeparatesSteadyShrinkFromAConstantScale) {
  const Trajectory gt = LoopTrajectory(400, 0, 5.0, 0.0);
  const Sim3 est_from_gt(3.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitY())), Eigen::Vector3d(1, 2, 3));
  Trajectory shrinking = gt;
  Eigen::Vector3d p = gt[0].world_from_cam.translation();
  for (size_t i = 1; i < gt.size(); ++i) {
    const double step_scale = 1.0 - 0.3 * static_cast<double>(i) / static_cast<double>(gt.size() - 1);
    p += step_scale * (gt[i].world_from_cam.translation() - gt[i - 1].world_from_cam.translation());
    shrinking[i].world_from_cam = SE3(gt[i].world_from_cam.rotation(), p);
  }
  EvalOptions options;
  options.scale_window_m = 4.0;
  EvalReport report;
  std::string error;
  ASSERT_TRUE(Evaluate({{"constant", gt, Transform(gt, est_from_gt)}, {"shrinking", gt, Transform(shrinking, est_from_gt)}},
                       options, &report, &error)) << error;
  const ScaleDrift& constant = report.agents[0].scale_drift;
  const ScaleDrift& drifting = report.agents[1].scale_drift;
  ASSERT_GE(constant.windows.size(), 5u);
  EXPECT_NEAR(constant.max_over_min, 1.0, 1e-6);
  EXPECT_NEAR(constant.windows.front().scale, 1.0, 1e-6);  // the agent's own alignment removed the 3x
  ASSERT_EQ(drifting.windows.size(), constant.windows.size());
  // Window scale = gt / est spread: 1 / step scale, ~1.0 in the first window, ~1/0.7 in the last.
  EXPECT_LT(drifting.windows.front().scale, drifting.windows.back().scale);
  // Each window sees the mean step scale of its stretch: the ratio is that of the first and
  // the last window's middle steps (1.30 here), not the whole flight's 1 / 0.7.
  auto step_scale_at = [&](const ScaleWindow& w) { return 1.0 - 0.3 * 0.5 * static_cast<double>(w.first + w.last) / (gt.size() - 1); };
  EXPECT_NEAR(drifting.max_over_min, step_scale_at(drifting.windows.front()) / step_scale_at(drifting.windows.back()), 0.03);
  EXPECT_GT(drifting.max_over_min, 1.25);
  for (size_t i = 1; i < drifting.windows.size(); ++i) EXPECT_GT(drifting.windows[i].scale, drifting.windows[i - 1].scale);
  options.scale_window_m = -1.0;
  EXPECT_FALSE(options.Validate(&error));
}

TEST(Evaluate, ClearErrors) {
  EvalReport report;
  std::string error;
  const Trajectory gt = LoopTrajectory(50, 0, 3.0, 0.0);
  Trajectory late = gt;
  for (StampedPose& p : late) p.stamp_ns += 5000000000LL;
  EXPECT_FALSE(Evaluate({{"x", gt, late}}, EvalOptions(), &report, &error));
  EXPECT_NE(error.find("agent 'x': no estimated pose"), std::string::npos) << error;
  EXPECT_FALSE(Evaluate({}, EvalOptions(), &report, &error));
  EvalOptions bad;
  bad.align_first_n = 0;
  EXPECT_FALSE(Evaluate({{"x", gt, gt}}, bad, &report, &error));
  bad = EvalOptions();
  bad.align_first_n = 10;  // first 10 poses only: still exact for an exact similarity
  ASSERT_TRUE(Evaluate({{"x", gt, gt}}, bad, &report, &error)) << error;
  EXPECT_LT(report.agents[0].ate_m.max, 1e-9);
}

TEST(Stats, PercentileAndPathLength) {
  EXPECT_EQ(Percentile({}, 0.5), 0.0);
  EXPECT_EQ(Percentile({5, 1, 3, 2, 4}, 0.5), 3.0);
  EXPECT_EQ(Percentile({5, 1, 3, 2, 4}, 0.0), 1.0);
  EXPECT_EQ(Percentile({5, 1, 3, 2, 4}, 1.0), 5.0);
  std::vector<double> hundred;
  for (int i = 1; i <= 100; ++i) hundred.push_back(i);
  EXPECT_EQ(Percentile(hundred, 0.95), 95.0);
  const std::vector<SE3> square = {SE3(Eigen::Quaterniond::Identity(), {0, 0, 0}),
                                   SE3(Eigen::Quaterniond::Identity(), {3, 0, 0}),
                                   SE3(Eigen::Quaterniond::Identity(), {3, 4, 0})};
  EXPECT_DOUBLE_EQ(PathLengthM(square), 7.0);
  EXPECT_EQ(PathLengthM({}), 0.0);
}

}  // namespace
}  // namespace ccm
