#include <gtest/gtest.h>

#include <set>
#include <thread>

#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

using testing::MapBuilder;

// Walks parent links from every keyframe: all must reach the single root without cycles.
void ExpectSpanningTree(const Map& map) {
  const auto kfs = map.keyframes();
  int roots = 0;
  for (const auto& kf : kfs) {
    if (!kf->parent().valid()) ++roots;
    KeyframeId cur = kf->id();
    std::set<KeyframeId> seen;
    while (cur.valid()) {
      ASSERT_TRUE(seen.insert(cur).second) << "cycle at " << cur;
      const auto node = map.keyframe(cur);
      ASSERT_NE(node, nullptr) << "dangling parent " << cur;
      const KeyframeId parent = node->parent();
      if (parent.valid()) {
        ASSERT_NE(map.keyframe(parent), nullptr);
        EXPECT_TRUE(map.keyframe(parent)->children().count(cur)) << "parent does not list child";
      }
      cur = parent;
    }
  }
  EXPECT_EQ(roots, 1);
}

// Chain of keyframes where neighbours share `strong` points and next-but-one share `weak`.
std::vector<KeyframeId> BuildChain(MapBuilder& b, int n, int strong, int weak) {
  std::vector<KeyframeId> ids;
  for (int i = 0; i < n; ++i) ids.push_back(b.AddKeyframe(i));
  for (int i = 0; i + 1 < n; ++i) b.AddSharedPoints({ids[i], ids[i + 1]}, strong);
  for (int i = 0; i + 2 < n; ++i) b.AddSharedPoints({ids[i], ids[i + 2]}, weak);
  for (const KeyframeId id : ids) b.map().UpdateConnections(id);
  return ids;
}

TEST(MapGraph, CovisibilityWeightsCountSharedPointsWithThreshold) {
  MapBuilder b;
  const auto ids = BuildChain(b, 5, 40, 14);
  const auto kf2 = b.map().keyframe(ids[2]);
  EXPECT_EQ(kf2->CovisibilityWeight(ids[1]), 40);
  EXPECT_EQ(kf2->CovisibilityWeight(ids[3]), 40);
  EXPECT_EQ(kf2->CovisibilityWeight(ids[0]), 0) << "14 shared points is below the 15 threshold";
  EXPECT_EQ(b.map().keyframe(ids[1])->CovisibilityWeight(ids[2]), 40) << "edges are symmetric";
  EXPECT_EQ(kf2->BestCovisible(1).front(), ids[1]) << "ties broken by id";
}

TEST(MapGraph, WeakOnlyNeighbourStillConnects) {
  MapBuilder b;
  const KeyframeId a = b.AddKeyframe(0), c = b.AddKeyframe(1);
  b.AddSharedPoints({a, c}, 5);
  b.map().UpdateConnections(c);
  EXPECT_EQ(b.map().keyframe(c)->CovisibilityWeight(a), 5);
  EXPECT_EQ(b.map().keyframe(c)->parent(), a);
}

TEST(MapGraph, SpanningTreeParentIsStrongestNeighbourAndSurvivesErasure) {
  MapBuilder b;
  const auto ids = BuildChain(b, 8, 60, 30);
  ExpectSpanningTree(b.map());
  EXPECT_EQ(b.map().keyframe(ids[3])->parent(), ids[2]);
  ASSERT_TRUE(b.map().EraseKeyframe(ids[3]));
  ExpectSpanningTree(b.map());
  // kf4's only remaining tree candidate with covisibility is kf2 (shares 30 points).
  EXPECT_EQ(b.map().keyframe(ids[4])->parent(), ids[2]);
  EXPECT_EQ(b.map().keyframe(ids[2])->CovisibilityWeight(ids[3]), 0);
}

TEST(MapGraph, ErasingTheRootRepeatedlyKeepsATree) {
  // The agent's bounded local map drops its oldest keyframes, which are tree roots.
  MapBuilder b;
  const auto ids = BuildChain(b, 10, 50, 20);
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(b.map().EraseKeyframe(ids[i]));
    ExpectSpanningTree(b.map());
  }
  EXPECT_EQ(b.map().num_keyframes(), 4u);
  EXPECT_FALSE(b.map().keyframe(ids[6])->parent().valid()) << "oldest survivor is the new root";
}

TEST(MapGraph, ErasingKeyframeDetachesObservationsAndErasesOrphans) {
  MapBuilder b;
  const KeyframeId a = b.AddKeyframe(0), c = b.AddKeyframe(1);
  const MapPointId shared = b.AddPointSeenBy({a, c});
  const MapPointId only_a = b.AddPointSeenBy({a});
  ASSERT_TRUE(b.map().EraseKeyframe(a));
  EXPECT_EQ(b.map().map_point(only_a), nullptr);
  const auto mp = b.map().map_point(shared);
  ASSERT_NE(mp, nullptr);
  EXPECT_EQ(mp->num_observations(), 1);
  EXPECT_EQ(mp->reference_kf(), c) << "reference moves to a surviving observer";
  EXPECT_EQ(b.map().keyframe(a), nullptr);
  // The bulk lookup: the same answers as one by one, in the order asked.
  const auto both = b.map().map_points({only_a, shared, only_a});
  ASSERT_EQ(both.size(), 3u);
  EXPECT_EQ(both[0], nullptr);
  EXPECT_EQ(both[1], mp);
  EXPECT_EQ(both[2], nullptr);
}

TEST(MapGraph, ReplaceMapPointMovesObservationsAndResolvesConflicts) {
  MapBuilder b;
  const KeyframeId k1 = b.AddKeyframe(0), k2 = b.AddKeyframe(1), k3 = b.AddKeyframe(2);
  const MapPointId keep = b.AddPointSeenBy({k1, k2});
  const MapPointId dup = b.AddPointSeenBy({k2, k3});  // k2 sees both: conflict
  ASSERT_TRUE(b.map().ReplaceMapPoint(dup, keep));
  EXPECT_EQ(b.map().map_point(dup), nullptr);
  const auto mp = b.map().map_point(keep);
  EXPECT_EQ(mp->num_observations(), 3);
  int k2_refs = 0;
  for (const MapPointId id : b.map().keyframe(k2)->map_points()) k2_refs += (id == keep) + (id == dup) * 100;
  EXPECT_EQ(k2_refs, 1) << "k2 keeps exactly one association to the kept point";
  EXPECT_TRUE(b.map().keyframe(k3)->MapPointAt(*mp->KeypointIn(k3)) == keep);
}

TEST(MapGraph, EssentialGraphHasTreeStrongCovisibilityAndLoopEdgesOnce) {
  MapBuilder b(800);
  const auto ids = BuildChain(b, 6, 120, 40);  // neighbours >= 100, skip-one pairs 40
  b.map().AddLoopEdge(ids[0], ids[5]);
  const EssentialGraph g = b.map().BuildEssentialGraph();
  EXPECT_EQ(g.nodes.size(), 6u);
  int tree = 0, covis = 0, loop = 0;
  std::set<std::pair<KeyframeId, KeyframeId>> seen;
  for (const auto& e : g.edges) {
    const auto key = std::minmax(e.a, e.b);
    EXPECT_TRUE(seen.insert(key).second) << "duplicate edge " << e.a << "-" << e.b;
    tree += e.type == EssentialGraph::EdgeType::kSpanningTree;
    covis += e.type == EssentialGraph::EdgeType::kCovisibility;
    loop += e.type == EssentialGraph::EdgeType::kLoop;
    if (e.type == EssentialGraph::EdgeType::kCovisibility) {
      EXPECT_GE(e.weight, 100);
    }
  }
  EXPECT_EQ(tree, 5);
  EXPECT_EQ(covis, 0) << "strong pairs are already tree edges; weight-40 pairs are below 100";
  EXPECT_EQ(loop, 1);
}

TEST(MapGraph, ConcurrentWritersOnDifferentKeyframesKeepBothSidesConsistent) {
  // Two handlers after a map fusion: each adds its own keyframes and points while the
  // other does the same, and connections are updated concurrently.
  MapBuilder b(400);
  std::vector<KeyframeId> ids;
  for (int i = 0; i < 20; ++i) ids.push_back(b.AddKeyframe(i));
  Map& map = b.map();
  auto writer = [&](AgentId agent, int first) {
    IdGenerator<MapPointId> gen(agent);
    for (int k = 0; k < 150; ++k) {
      const MapPointId id = gen.Next();
      map.AddMapPoint(std::make_shared<MapPoint>(id, Eigen::Vector3d(0, 0, 4), ids[first], OrbDescriptor{}));
      for (int j = 0; j < 3; ++j) map.AddObservation(ids[first + (k + j) % 10], k, id);
      if (k % 10 == 0) map.UpdateConnections(ids[first + k % 10]);
    }
  };
  std::thread t1(writer, 7, 0), t2(writer, 8, 10);
  t1.join();
  t2.join();
  for (const auto& mp : map.map_points()) {
    for (const auto& [kf, idx] : mp->observations()) EXPECT_EQ(map.keyframe(kf)->MapPointAt(idx), mp->id());
  }
  EXPECT_EQ(map.num_map_points(), 300u);
}

}  // namespace
}  // namespace ccm
