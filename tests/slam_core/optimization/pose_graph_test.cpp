#include "slam_core/optimization/pose_graph.h"

#include <gtest/gtest.h>

#include <random>

#include "synthetic_scene.h"

namespace ccm::opt {
namespace {

constexpr int kNumKeyframes = 100;
// Information multiplier of the loop edge: its Sim(3) comes from hundreds of matched points,
// while the chain has 3 edges per keyframe (spanning tree + 2 covisibility). With weight 1
// the chain absorbs only 7/8 of the loop's scale error (ORB-SLAM gets the same effect from
// many loop edges between the corrected neighbourhoods).
constexpr double kLoopWeight = 10.0;

// Ground truth: a circle of radius 10 m, camera looking along the direction of travel.
std::vector<SE3> CircleTrajectory() {
  std::vector<SE3> poses;
  for (int i = 0; i < kNumKeyframes; ++i) {
    const double th = 2.0 * M_PI * i / kNumKeyframes;
    const Eigen::Vector3d z(-std::sin(th), std::cos(th), 0.0);
    const Eigen::Vector3d y(0, 0, -1);
    Eigen::Matrix3d R;
    R << y.cross(z), y, z;
    poses.emplace_back(R, Eigen::Vector3d(10 * std::cos(th), 10 * std::sin(th), 0.3 * std::sin(3 * th)));
  }
  return poses;
}

// Odometry with a rotation bias, rotation/translation noise and shrinking scale (0.5% per
// keyframe, 0.6x at the end of the loop), like monocular VO drift.
std::vector<SE3> Drift(const std::vector<SE3>& truth, std::vector<double>* local_scale) {
  std::mt19937 rng(21);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<SE3> drifted{truth[0]};
  local_scale->assign(1, 1.0);
  const Eigen::Quaterniond bias(Eigen::AngleAxisd(0.25 * M_PI / 180, Eigen::Vector3d(0.2, 1.0, 0.3).normalized()));
  for (size_t i = 1; i < truth.size(); ++i) {
    const SE3 rel = truth[i - 1].inverse() * truth[i];
    const double s = local_scale->back() * 0.995;
    const Eigen::Vector3d w = 0.001 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const Eigen::Quaterniond noise(Eigen::AngleAxisd(w.norm(), w.normalized()));
    const Eigen::Vector3d t = s * rel.translation() + 0.005 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    drifted.push_back(drifted.back() * SE3(bias * noise * rel.rotation(), t));
    local_scale->push_back(s);
  }
  return drifted;
}

double AtePositionRmse(const std::vector<Eigen::Vector3d>& est, const std::vector<SE3>& truth) {
  double sum = 0;
  for (size_t i = 0; i < est.size(); ++i) sum += (est[i] - truth[i].translation()).squaredNorm();
  return std::sqrt(sum / est.size());
}

TEST(PoseGraph, ClosesLoopWithScaleDriftAndReducesAteMoreThan5x) {
  const std::vector<SE3> truth = CircleTrajectory();
  std::vector<double> local_scale;
  const std::vector<SE3> drifted = Drift(truth, &local_scale);
  PoseGraphProblem g;
  for (int i = 0; i < kNumKeyframes; ++i) g.nodes.push_back(Sim3Node{static_cast<std::uint64_t>(i), Sim3(drifted[i]), i == 0});
  // Spanning tree and covisibility edges from the (drifted) current estimates, as ORB-SLAM.
  for (int i = 0; i + 1 < kNumKeyframes; ++i) {
    for (int d = 1; d <= 3 && i + d < kNumKeyframes; ++d) {
      const Sim3Edge e{i, i + d, Sim3(drifted[i].inverse() * drifted[i + d]), 1.0,
                       d == 1 ? Sim3EdgeKind::kSpanningTree : Sim3EdgeKind::kCovisibility};
      g.edges.push_back(e);
    }
  }
  // Loop edge last -> first, measured in the last keyframe's (drifted) local scale.
  const int last = kNumKeyframes - 1;
  const SE3 rel = truth[last].inverse() * truth[0];
  const double s = local_scale[last];
  g.edges.push_back(Sim3Edge{last, 0, Sim3(s, rel.rotation(), s * rel.translation()), kLoopWeight, Sim3EdgeKind::kLoop});

  std::vector<Eigen::Vector3d> before, after;
  for (const Sim3Node& n : g.nodes) before.push_back(n.world_from_cam.translation());
  const OptimizationSummary summary = OptimizePoseGraph(&g);
  ASSERT_TRUE(summary.usable) << summary.message;
  for (const Sim3Node& n : g.nodes) after.push_back(n.world_from_cam.translation());
  const double ate_before = AtePositionRmse(before, truth);
  const double ate_after = AtePositionRmse(after, truth);
  EXPECT_GT(ate_before, 1.0);
  EXPECT_LT(ate_after, ate_before / 5.0) << "before " << ate_before << " after " << ate_after;
  // The scale drift is undone: node scales follow 1 / local scale.
  EXPECT_NEAR(g.nodes[last].world_from_cam.scale(), 1.0 / s, 0.02 / s);
  // Sim(3)-aligned ATE improves as well (drift is not just a global similarity).
  std::vector<SE3> after_rigid, before_rigid;
  for (int i = 0; i < kNumKeyframes; ++i) {
    after_rigid.push_back(RigidPose(g.nodes[i].world_from_cam));
    before_rigid.push_back(drifted[i]);
  }
  EXPECT_LT(testing::AlignedPoseErrors(after_rigid, truth).rmse_position_m,
            testing::AlignedPoseErrors(before_rigid, truth).rmse_position_m / 5.0);
}

TEST(PoseGraph, CorrectPointsByReferenceFollowsKeyframeCorrection) {
  const SE3 before(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY())), Eigen::Vector3d(1, 2, 3));
  const Sim3 after(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(-1, 0, 1));
  PoseGraphProblem g;
  g.nodes.push_back(Sim3Node{0, after, false});
  const Eigen::Vector3d p_cam(0.5, -0.2, 4.0);
  std::vector<Eigen::Vector3d> points{before * p_cam, Eigen::Vector3d(7, 7, 7)};
  EXPECT_EQ(CorrectPointsByReference({before}, g, {0, -1}, &points), 1);
  // In the corrected rigid pose, the point sits on the same ray at s times the depth.
  const Eigen::Vector3d in_new_cam = RigidPose(after).inverse() * points[0];
  EXPECT_LT((in_new_cam - 2.0 * p_cam).norm(), 1e-12);
  EXPECT_EQ(points[1], Eigen::Vector3d(7, 7, 7));
}

TEST(PoseGraph, ResidualIsZeroForConsistentMeasurement) {
  const Sim3 a(1.5, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())), Eigen::Vector3d(1, 0, 2));
  const Sim3 b(0.7, Eigen::Quaterniond(Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(0, 3, 1));
  const Sim3Edge e{0, 1, a.inverse() * b, 1.0, Sim3EdgeKind::kOther};
  EXPECT_LT(Sim3EdgeResidual(a, b, e).norm(), 1e-12);
  const Sim3Edge off{0, 1, Sim3(1.1, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()) * (a.inverse() * b), 4.0,
                     Sim3EdgeKind::kOther};
  EXPECT_NEAR(std::abs(Sim3EdgeResidual(a, b, off)[6]), 2.0 * std::log(1.1), 1e-12);
}

TEST(PoseGraph, InvalidEdgeIsRejected) {
  PoseGraphProblem g;
  g.nodes.resize(2);
  g.edges.push_back(Sim3Edge{0, 5, Sim3(), 1.0, Sim3EdgeKind::kOther});
  EXPECT_FALSE(OptimizePoseGraph(&g).usable);
}

}  // namespace
}  // namespace ccm::opt
