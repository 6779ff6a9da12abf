// Generated scenes (scene_generator.h) and the overlap ground truth (overlap_truth.h).
#include <set>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tests/sim/overlap_truth.h"
#include "tests/sim/scenario.h"
#include "tests/sim/scene_generator.h"
#include "tests/sim/simulation.h"

namespace ccm::sim {
namespace {

Scenario Parse(const std::string& yaml) {
  std::string error;
  const auto s = ParseScenarioYaml(yaml, "generated", &error);
  EXPECT_TRUE(s) << error << "\n" << yaml;
  return s ? *s : Scenario{};
}

bool InsideBox(const ObjectSpec& o, const Eigen::Vector3d& p, double margin) {
  const Eigen::Vector2d c = 0.5 * (o.min + o.max).head<2>();
  const double yaw = -o.yaw_deg * M_PI / 180.0;
  const Eigen::Vector2d d = Eigen::Rotation2Dd(yaw) * (p.head<2>() - c);
  const Eigen::Vector2d half = 0.5 * (o.max - o.min).head<2>();
  return std::abs(d.x()) < half.x() + margin && std::abs(d.y()) < half.y() + margin && p.z() < o.max.z() &&
         p.z() > o.min.z();
}

TEST(SceneGenerator, SameSeedSameSceneOtherSeedOtherScene) {
  EXPECT_EQ(GenerateScene(17).yaml, GenerateScene(17).yaml);
  EXPECT_NE(GenerateScene(17).yaml, GenerateScene(18).yaml);
  EXPECT_EQ(GeneratedScenarioYaml("gen:17"), GenerateScene(17).yaml);
  EXPECT_FALSE(GeneratedScenarioYaml("gen:"));
  EXPECT_FALSE(GeneratedScenarioYaml("gen:12x"));
  SceneGeneratorOptions four;
  four.max_agents = 4;
  EXPECT_EQ(GeneratedScenarioYaml("gen:13:4"), GenerateScene(13, four).yaml);
  EXPECT_NE(GeneratedScenarioYaml("gen:13:4"), GenerateScene(13).yaml);  // another draw: another scene
  EXPECT_FALSE(GeneratedScenarioYaml("gen:13:"));
  EXPECT_FALSE(GeneratedScenarioYaml("gen::4"));
  EXPECT_FALSE(GeneratedScenarioYaml("gen:13:1"));   // fewer than min_agents
  EXPECT_FALSE(GeneratedScenarioYaml("gen:13:17"));  // more than the generator holds
  EXPECT_FALSE(GeneratedScenarioYaml("gen:13:4:2"));
  EXPECT_FALSE(GeneratedScenarioYaml("hall3"));
  std::string error;
  EXPECT_TRUE(LoadScenario("gen:5", &error)) << error;
}

// Every scene of the distribution is valid and flyable: agents inside the space, never
// inside an object, every trajectory long enough for the flight; and the distribution
// covers what the benchmark promises (layouts, team sizes, overlap kinds, cameras).
TEST(SceneGenerator, ScenesAreValidFlyableAndVaried) {
  std::set<std::string> layouts, cameras, profiles, kinds;
  std::set<int> team_sizes;
  int planned = 0, flown = 0, fast = 0, flights = 0;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    const GeneratedScene g = GenerateScene(seed);
    const Scenario s = Parse(g.yaml);
    ASSERT_EQ(s.Validate(), "") << "seed " << seed;
    layouts.insert(SceneLayoutName(g.layout));
    cameras.insert(g.camera);
    profiles.insert(g.texture_profile);
    team_sizes.insert(g.num_agents);
    for (const PlannedOverlap& p : g.plan) {
      kinds.insert(PlannedOverlapName(p.kind));
      if (p.kind == PlannedOverlapKind::kNone) continue;
      ++planned;
      flown += p.flown;
    }
    ASSERT_EQ(static_cast<int>(s.agents.size()), g.num_agents);
    Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);  // the space: the room, or the yard's ground
    for (const ObjectSpec& o : s.world.objects) {
      if (o.kind == ObjectKind::kRoom) lo = o.min.head<2>(), hi = o.max.head<2>();
      if (o.kind == ObjectKind::kPanel && o.normal.z() > 0.9) {
        lo = lo.cwiseMin(o.min.head<2>() - 0.5 * o.max.head<2>());
        hi = hi.cwiseMax(o.min.head<2>() + 0.5 * o.max.head<2>());
      }
    }
    for (const AgentSpec& a : s.agents) {
      std::string error;
      const auto traj = Trajectory::Create(a.trajectory, &error);
      ASSERT_TRUE(traj) << "seed " << seed << " " << a.name << ": " << error;
      double max_rate = 0.0;
      for (double t = 0.0; t + 0.05 <= traj->duration_s(); t += 0.05) {
        const Eigen::Quaterniond a = traj->WorldFromCam(t).rotation(), b = traj->WorldFromCam(t + 0.05).rotation();
        max_rate = std::max(max_rate, Eigen::AngleAxisd(a.conjugate() * b).angle() * 180.0 / M_PI / 0.05);
      }
      // Drone footage, not whip pans: planned under 125 deg/s (EuRoC peaks near 90); the few
      // loops that could not be slowed enough stay under 200.
      EXPECT_LT(max_rate, 200.0) << "seed " << seed << " " << a.name;
      fast += max_rate > 125.0;
      ++flights;
      for (double t = 0.0; t <= traj->duration_s(); t += 0.1) {
        const Eigen::Vector3d p = traj->Position(t);
        ASSERT_TRUE(p.x() > lo.x() + 0.3 && p.y() > lo.y() + 0.3 && p.x() < hi.x() - 0.3 && p.y() < hi.y() - 0.3)
            << "seed " << seed << " " << a.name << " leaves the space at t=" << t << ": " << p.transpose();
        for (const ObjectSpec& o : s.world.objects) {
          if (o.kind != ObjectKind::kBox && o.kind != ObjectKind::kPillar) continue;
          ASSERT_FALSE(InsideBox(o, p, 0.15)) << "seed " << seed << " " << a.name << " flies into " << o.name
                                              << " at t=" << t;
        }
      }
      // At least one lap and a bit: every agent comes back to where it flew.
      const double loop = [&] {
        double len = 0.0;
        const auto& w = a.trajectory.waypoints;
        for (size_t i = 0; i < w.size(); ++i) len += (w[(i + 1) % w.size()].position_m - w[i].position_m).norm();
        return len;
      }();
      EXPECT_GT(traj->ArcLength(traj->duration_s()), 1.1 * loop) << "seed " << seed << " " << a.name;
    }
  }
  // At least half of the planned overlaps are flown (the rest fly plain loops beside their
  // target: the ground truth, not the plan, says which pairs overlap), and almost every
  // flight turns at most 125 deg/s.
  EXPECT_GE(2 * flown, planned) << flown << " of " << planned << " planned overlaps flown";
  EXPECT_LE(20 * fast, flights) << fast << " of " << flights << " flights turn faster than 125 deg/s";
  EXPECT_EQ(layouts.size(), 4u);
  EXPECT_GE(team_sizes.size(), 6u);
  EXPECT_EQ(kinds.size(), 5u);
  EXPECT_EQ(cameras.size(), 4u);
  EXPECT_EQ(profiles.size(), 3u);
}

// Ground truth on the built-in scenes whose overlaps are known: every hall3 pair shares
// views, disjoint2's two rooms never do, and every hall3 agent revisits its own path.
TEST(OverlapTruth, KnownScenes) {
  std::string error;
  const auto hall = Simulation::Create(*LoadScenario("hall3", &error), &error);
  ASSERT_TRUE(hall) << error;
  OverlapTruthOptions o;
  o.sample_hz = 2.0;
  const OverlapTruth h = OverlapTruth::Compute(*hall, o);
  ASSERT_EQ(h.pairs().size(), 3u);
  for (const PairTruth& p : h.pairs()) {
    EXPECT_TRUE(p.qualifies) << p.a << "-" << p.b << ": " << p.seconds_a << "/" << p.seconds_b << " s";
    EXPECT_GE(p.first_s, 0.0);
  }
  for (const AgentTruth& a : h.agents()) EXPECT_TRUE(a.revisits);

  const auto disjoint = Simulation::Create(*LoadScenario("disjoint2", &error), &error);
  ASSERT_TRUE(disjoint) << error;
  const OverlapTruth d = OverlapTruth::Compute(*disjoint, o);
  ASSERT_EQ(d.pairs().size(), 1u);
  EXPECT_FALSE(d.pairs()[0].overlaps);
  EXPECT_EQ(d.pairs()[0].kind, "none");
}

// A team-scale scene (issue 30: 16 distinct agents in one map): 16 agents in a 4 x 4 grid of
// cells of a hall or a yard, each neighbouring pair planned (24 pairs), every flight valid;
// 17 agents are refused.
TEST(SceneGenerator, TeamScaleScenesHoldSixteenAgentsInAFourByFourGrid) {
  SceneGeneratorOptions go;
  go.min_agents = go.max_agents = kMaxGeneratedAgents;
  ASSERT_EQ(go.Validate(), "");
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const GeneratedScene g = GenerateScene(seed, go);
    ASSERT_EQ(g.num_agents, 16);
    EXPECT_TRUE(g.layout == SceneLayout::kHall || g.layout == SceneLayout::kYard) << SceneLayoutName(g.layout);
    EXPECT_EQ(g.plan.size(), 24u) << "seed " << seed;
    int overlapping = 0;
    for (const PlannedOverlap& p : g.plan) overlapping += p.kind != PlannedOverlapKind::kNone;
    EXPECT_GE(overlapping, 1);
    const Scenario s = Parse(g.yaml);
    ASSERT_EQ(s.Validate(), "") << "seed " << seed;
    ASSERT_EQ(s.agents.size(), 16u);
    for (const AgentSpec& a : s.agents) {
      std::string error;
      const auto traj = Trajectory::Create(a.trajectory, &error);
      ASSERT_TRUE(traj) << "seed " << seed << " " << a.name << ": " << error;
      EXPECT_GE(traj->duration_s(), go.min_duration_s - 1e-6);
    }
  }
  go.max_agents = kMaxGeneratedAgents + 1;
  EXPECT_NE(go.Validate(), "");
}

// The planned overlaps are real: a generated scene's pairs planned "same" or "long" share
// views in the ground truth for about as long as planned, and the view of the same pose
// with itself is fully shared at zero angle.
TEST(OverlapTruth, PlannedOverlapsAreSeen) {
  int checked = 0;
  for (std::uint64_t seed = 1; seed <= 40 && checked < 2; ++seed) {
    SceneGeneratorOptions go;
    go.max_agents = 3;
    const GeneratedScene g = GenerateScene(seed, go);
    bool wanted = false;
    for (const PlannedOverlap& p : g.plan) {
      wanted = wanted || (p.flown && (p.kind == PlannedOverlapKind::kSame || p.kind == PlannedOverlapKind::kLong));
    }
    if (!wanted || g.layout == SceneLayout::kYard) continue;  // yards: slow to build, covered by the bench
    std::string error;
    const auto sim = Simulation::Create(Parse(g.yaml), &error);
    ASSERT_TRUE(sim) << error;
    OverlapTruthOptions o;
    o.sample_hz = 2.0;
    const OverlapTruth t = OverlapTruth::Compute(*sim, o);
    for (const PlannedOverlap& p : g.plan) {
      if (!p.flown || (p.kind != PlannedOverlapKind::kSame && p.kind != PlannedOverlapKind::kLong)) continue;
      const PairTruth& pt = t.pair(p.agent_a, p.agent_b);
      EXPECT_TRUE(pt.overlaps) << "seed " << seed << " pair " << p.agent_a << "-" << p.agent_b;
      EXPECT_GE(std::min(pt.seconds_a, pt.seconds_b), 0.5 * p.seconds)
          << "seed " << seed << " pair " << p.agent_a << "-" << p.agent_b << " planned " << p.seconds << " s";
    }
    const SampledView v = t.Sample(*sim, sim->trajectory(0).WorldFromCam(3.0), 3.0);
    const ViewOverlap self = t.Compare(v, v);
    EXPECT_TRUE(self.covisible);
    EXPECT_DOUBLE_EQ(self.share_a, 1.0);
    EXPECT_NEAR(self.angle_deg, 0.0, 1e-3);
    ++checked;
  }
  EXPECT_EQ(checked, 2);
}

}  // namespace
}  // namespace ccm::sim
