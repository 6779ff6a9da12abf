#include <cmath>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tests/sim/sim_test_util.h"

namespace ccm::sim {
namespace {

using testing::BuiltinOrDie;

double AngleBetween(const SE3& a, const SE3& b) { return a.rotation().angularDistance(b.rotation()); }

class BuiltinTrajectories : public ::testing::TestWithParam<std::string> {};

TEST_P(BuiltinTrajectories, SmoothAndWithinSpeedBounds) {
  const Scenario s = BuiltinOrDie(GetParam());
  for (const AgentSpec& a : s.agents) {
    std::string error;
    auto traj = Trajectory::Create(a.trajectory, &error);
    ASSERT_TRUE(traj) << error;
    EXPECT_GE(a.trajectory.duration_s, 60.0);
    EXPECT_LE(a.trajectory.duration_s, 90.0);
    const double dt = 1.0 / a.rate_hz;
    Eigen::Vector3d prev_v = traj->Velocity(0.0);
    double prev_w = 0.0;
    for (double t = dt; t <= a.trajectory.duration_s; t += dt) {
      const Eigen::Vector3d v = traj->Velocity(t);
      ASSERT_GE(v.norm(), 0.3) << a.name << " t=" << t;
      ASSERT_LE(v.norm(), 1.5) << a.name << " t=" << t;
      EXPECT_GE(v.norm(), a.trajectory.min_speed_mps * 0.99);
      EXPECT_LE(v.norm(), a.trajectory.max_speed_mps * 1.01);
      EXPECT_LT((v - prev_v).norm() / dt, 2.0) << a.name << " acceleration at t=" << t;
      const double w = AngleBetween(traj->WorldFromCam(t - dt), traj->WorldFromCam(t)) / dt;
      EXPECT_LT(w, 1.2) << a.name << " angular rate at t=" << t;
      EXPECT_LT(std::abs(w - prev_w) / dt, 6.0) << a.name << " angular acceleration at t=" << t;
      prev_v = v;
      prev_w = w;
    }
  }
}

// The camera keeps 0.4 m from every wall, box and pillar.
TEST_P(BuiltinTrajectories, KeepsClearOfObjects) {
  const Scenario s = BuiltinOrDie(GetParam());
  for (const AgentSpec& a : s.agents) {
    auto traj = Trajectory::Create(a.trajectory, nullptr);
    ASSERT_TRUE(traj);
    for (double t = 0; t <= a.trajectory.duration_s; t += 0.1) {
      const Eigen::Vector3d p = traj->Position(t);
      bool in_a_room = false;
      for (const ObjectSpec& o : s.world.objects) {
        if (o.kind == ObjectKind::kRoom) {
          in_a_room |= (p.array() > o.min.array() + 0.4).all() && (p.array() < o.max.array() - 0.4).all();
        } else if (o.kind != ObjectKind::kPanel) {
          const Eigen::Vector3d c = 0.5 * (o.min + o.max), h = 0.5 * (o.max - o.min);
          const Eigen::Vector3d local =
              Eigen::AngleAxisd(-o.yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()) * (p - c);
          EXPECT_FALSE((local.cwiseAbs().array() < h.array() + 0.4).all())
              << a.name << " at t=" << t << " is within 0.4 m of " << o.name;
        }
      }
      EXPECT_TRUE(in_a_room) << a.name << " at t=" << t << " leaves the room: " << p.transpose();
    }
  }
}

// Every agent comes back to a place it saw at least 20 s earlier, looking a similar way.
TEST_P(BuiltinTrajectories, EveryAgentRevisitsItsPath) {
  const Scenario s = BuiltinOrDie(GetParam());
  for (const AgentSpec& a : s.agents) {
    auto traj = Trajectory::Create(a.trajectory, nullptr);
    bool revisit = false;
    for (double t1 = 0; t1 < a.trajectory.duration_s && !revisit; t1 += 0.5)
      for (double t2 = t1 + 20; t2 <= a.trajectory.duration_s && !revisit; t2 += 0.5)
        revisit = (traj->Position(t1) - traj->Position(t2)).norm() < 0.5 &&
                  AngleBetween(traj->WorldFromCam(t1), traj->WorldFromCam(t2)) < 0.35;
    EXPECT_TRUE(revisit) << a.name;
  }
}

INSTANTIATE_TEST_SUITE_P(Sim, BuiltinTrajectories, ::testing::Values("hall3", "disjoint2", "repeated"));

TEST(Trajectory, OpenPathStartsAtFirstWaypointAndRejectsTooShortFlights) {
  TrajectorySpec spec;
  spec.loop = false;
  spec.waypoints = {{Eigen::Vector3d(0, 0, 1), 0}, {Eigen::Vector3d(5, 0, 1.5), 0}, {Eigen::Vector3d(5, 5, 1), 0}};
  spec.duration_s = 8.0;
  spec.min_speed_mps = 0.5;
  spec.max_speed_mps = 1.0;
  std::string error;
  auto traj = Trajectory::Create(spec, &error);
  ASSERT_TRUE(traj) << error;
  EXPECT_LT((traj->Position(0) - Eigen::Vector3d(0, 0, 1)).norm(), 1e-9);
  // Camera looks along the direction of travel (+x) at the start, pitched down.
  const Eigen::Vector3d forward = traj->WorldFromCam(0).rotation() * Eigen::Vector3d::UnitZ();
  EXPECT_GT(forward.x(), 0.95);
  EXPECT_LT(forward.z(), -0.1);
  spec.duration_s = 60.0;
  EXPECT_FALSE(Trajectory::Create(spec, &error));
  EXPECT_NE(error.find("too short"), std::string::npos) << error;
  spec.waypoints.pop_back();
  spec.waypoints.pop_back();
  EXPECT_FALSE(Trajectory::Create(spec, &error));
  EXPECT_NE(error.find("at least 2 waypoints"), std::string::npos) << error;
}

}  // namespace
}  // namespace ccm::sim
