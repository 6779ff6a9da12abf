// DriftPath: the path along which drift can build up between two keyframes of one map
// (the server's bound on loop corrections, also between two agents of a fused map).
#include <gtest/gtest.h>

#include "slam_core/map/drift_path.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

// Agent 1 flies x = 0..4 m on y = 0, agent 2 x = 0..4 m on y = 10 (1 m between keyframes).
struct TwoAgents {
  testing::MapBuilder b;
  std::vector<KeyframeId> a1, a2;
  TwoAgents() {
    for (int i = 0; i < 5; ++i) a1.push_back(b.AddKeyframeAt({static_cast<double>(i), 0, 0}, 1));
    for (int i = 0; i < 5; ++i) a2.push_back(b.AddKeyframeAt({static_cast<double>(i), 10, 0}, 2));
  }
  void Share(KeyframeId x, KeyframeId y, int points) {
    b.AddSharedPoints({x, y}, points);
    b.map().UpdateConnections(x);
  }
};

TEST(DriftPath, SameAgentIsThePathThroughItsKeyframesBetweenTheTwo) {
  testing::MapBuilder b;
  const KeyframeId k0 = b.AddKeyframeAt({0, 0, 0});
  const KeyframeId k1 = b.AddKeyframeAt({3, 0, 0});
  const KeyframeId k2 = b.AddKeyframeAt({3, 4, 0});
  const KeyframeId k3 = b.AddKeyframeAt({0, 4, 0});
  EXPECT_NEAR(*DriftPath(b.map(), k0, k3), 10.0, 1e-9) << "the path flown, not the 4 m straight line";
  EXPECT_NEAR(*DriftPath(b.map(), k3, k0), 10.0, 1e-9);
  EXPECT_NEAR(*DriftPath(b.map(), k1, k2), 4.0, 1e-9);
  EXPECT_NEAR(*DriftPath(b.map(), k2, k2), 0.0, 1e-9);
  EXPECT_NEAR(*DriftPath(b.map(), k1, KeyframeId::Make(1, 99)), 7.0, 1e-9) << "a removed end: the path still there";
}

TEST(DriftPath, TwoAgentsMeetThroughTheClosestJunction) {
  TwoAgents t;
  // Junctions: agent 1 at x = 4 with agent 2 at x = 0 (route 0 -> 4 on agent 1, then 0 -> 4
  // on agent 2: 8 m), and agent 1 at x = 1 with agent 2 at x = 1 (1 + 3 = 4 m).
  t.Share(t.a1[4], t.a2[0], 20);
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[0], t.a2[4]), 8.0, 1e-9);
  t.Share(t.a1[1], t.a2[1], 20);
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[0], t.a2[4]), 4.0, 1e-9);
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a2[4], t.a1[0]), 4.0, 1e-9) << "symmetric";
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[1], t.a2[1]), 0.0, 1e-9) << "already joined there";
}

TEST(DriftPath, AThirdAgentJoinsTwoWhoseMapsNeverMet) {
  // Agent 3 flies x = 0..4 m on y = 20. It met agent 1 at agent 1's x = 4 (its own x = 0)
  // and agent 2 at x = 2 (its own x = 4); agents 1 and 2 share nothing.
  TwoAgents t;
  std::vector<KeyframeId> a3;
  for (int i = 0; i < 5; ++i) a3.push_back(t.b.AddKeyframeAt({static_cast<double>(i), 20, 0}, 3));
  t.Share(t.a1[4], a3[0], 20);
  t.Share(a3[4], t.a2[2], 20);
  t.Share(t.a1[0], t.a2[0], 10);  // too weak to be a junction
  // 4 m along agent 1, 4 m along agent 3, 2 m along agent 2.
  const auto via_3 = DriftPath(t.b.map(), t.a1[0], t.a2[4]);
  ASSERT_TRUE(via_3) << "no route found through agent 3";
  EXPECT_NEAR(*via_3, 10.0, 1e-9);
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a2[4], t.a1[0]), 10.0, 1e-9) << "symmetric";
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[3], a3[2]), 3.0, 1e-9);
  // A direct junction of 1 and 2 at their x = 0 is shorter: 4 m along agent 2 only.
  t.Share(t.a1[0], t.a2[0], 10);
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[0], t.a2[4]), 4.0, 1e-9);
  // Without agent 3's keyframe at the first junction, agent 1 reaches agent 3 only through
  // agent 2: 4 m back along agent 1, then 2 m along agent 2.
  ASSERT_TRUE(t.b.map().EraseKeyframe(a3[0]));
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[4], a3[4]), 6.0, 1e-9);
}

TEST(DriftPath, WeakLinksAreNoJunction) {
  TwoAgents t;
  t.Share(t.a1[4], t.a2[0], 20);
  t.Share(t.a1[0], t.a2[4], 10);  // below the map's covisibility threshold (15)
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[0], t.a2[4]), 8.0, 1e-9);
  t.Share(t.a1[0], t.a2[4], 10);  // now 20: a junction at the map's threshold ...
  EXPECT_NEAR(*DriftPath(t.b.map(), t.a1[0], t.a2[4], 15), 0.0, 1e-9);
  EXPECT_FALSE(DriftPath(t.b.map(), t.a1[0], t.a2[4], 30)) << "... but neither of the two has 30 shared points";
}

TEST(DriftPath, NoJunctionOrUnknownKeyframeGivesNoPath) {
  TwoAgents t;
  EXPECT_FALSE(DriftPath(t.b.map(), t.a1[0], t.a2[4])) << "two agents that share no points";
  t.Share(t.a1[4], t.a2[0], 20);
  EXPECT_FALSE(DriftPath(t.b.map(), t.a1[0], KeyframeId::Make(2, 99))) << "a keyframe not in the map";
  EXPECT_FALSE(DriftPath(t.b.map(), KeyframeId::Make(3, 1), t.a2[0])) << "an agent not in the map";
}

}  // namespace
}  // namespace ccm
