// ChangePacker with objects the server sent back (map sharing with
// share_own_keyframes_after_s): an agent's own old keyframes and points that return from the
// server are the server's already, so they never leave again, and new data that refers to
// them is not held back waiting for them to be sent. And near-duplicate keyframes sent as
// pose anchors: resent as anchors while what they duplicate is still there, else in full.
#include <gtest/gtest.h>

#include "slam_core/vo/change_packer.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

TEST(ChangePacker, OwnKeyframesAndPointsTheServerSentBackNeverLeaveAgain) {
  testing::MapBuilder builder(200);
  Map& map = builder.map();
  const KeyframeId returned = builder.AddKeyframe(0.0);  // an old keyframe of agent 1, back from the server
  const KeyframeId fresh = builder.AddKeyframe(0.5);     // made by the VO just now
  std::vector<MapPointId> old_points, new_points;
  for (int i = 0; i < 20; ++i) old_points.push_back(builder.AddPointSeenBy({returned, fresh}));
  for (int i = 0; i < 20; ++i) new_points.push_back(builder.AddPointSeenBy({returned, fresh}));  // referenced to `returned`
  map.keyframe(returned)->MarkFromServer();
  for (const MapPointId id : old_points) map.map_point(id)->MarkFromServer();

  ChangePacker packer(1);
  VoChanges changes;
  changes.map = std::shared_ptr<Map>(&map, [](Map*) {});
  changes.keyframes = {returned, fresh};
  changes.map_points.insert(old_points.begin(), old_points.end());
  changes.map_points.insert(new_points.begin(), new_points.end());
  changes.reference_kf = fresh;
  const AgentBatch first = packer.Pack(changes, 0);
  ASSERT_EQ(first.keyframes.size(), 1u);
  EXPECT_EQ(first.keyframes[0].id, fresh);
  std::set<MapPointId> sent;
  for (const MapPointData& p : first.map_points) sent.insert(p.id);
  for (const MapPointId id : old_points) EXPECT_EQ(sent.count(id), 0u) << "a point the server sent back left again";
  for (const MapPointId id : new_points) EXPECT_EQ(sent.count(id), 1u) << "a new point waits for a keyframe the server has";
  EXPECT_EQ(packer.deferred(), 0u) << "nothing may wait for the returned keyframe to be sent: it never will be";

  // Local BA moved both keyframes: only the agent's own new one is updated.
  const AgentBatch second = packer.Pack(changes, 1);
  EXPECT_TRUE(second.keyframes.empty());
  for (const KeyframePoseUpdate& u : second.keyframe_updates) EXPECT_NE(u.id, returned);
}

TEST(ChangePacker, AnAnchorWhoseBaseLeftTheMapIsResentInFullAndCounted) {
  testing::MapBuilder builder(200);
  Map& map = builder.map();
  const KeyframeId a = builder.AddKeyframe(0.0), c = builder.AddKeyframe(0.1);
  ChangePackerOptions options;
  options.anchor_duplicates = NearDuplicateRule{};
  ChangePacker packer(1, options);
  VoChanges changes;
  changes.map = std::shared_ptr<Map>(&map, [](Map*) {});
  changes.keyframes = {a, c};
  changes.reference_kf = c;
  ASSERT_EQ(packer.Pack(changes, 0).keyframes.size(), 2u);
  // A keyframe between the two, seeing what both see: a near-duplicate, sent as an anchor.
  const KeyframeId b = builder.AddKeyframe(0.05);
  for (int i = 0; i < 60; ++i) builder.AddPointSeenBy({a, c, b});
  for (const KeyframeId k : {a, c, b}) map.UpdateConnections(k);
  changes.keyframes = {b};
  changes.map_points.clear();
  const AgentBatch first = packer.Pack(changes, 1);
  ASSERT_EQ(first.keyframes.size(), 1u);
  EXPECT_TRUE(first.keyframes[0].anchor_only);
  EXPECT_EQ(packer.anchors_sent(), 1u);

  changes.keyframes.clear();
  packer.Resend(b);  // never acknowledged: its base is still here, so again as an anchor
  const AgentBatch again = packer.Pack(changes, 2);
  ASSERT_EQ(again.keyframes.size(), 1u);
  EXPECT_TRUE(again.keyframes[0].anchor_only);
  EXPECT_EQ(packer.anchors_resent_in_full(), 0u);

  ASSERT_TRUE(map.EraseKeyframe(a));
  ASSERT_TRUE(map.EraseKeyframe(c));
  packer.Resend(b);  // what it duplicates left the local map: only the full keyframe places it
  const AgentBatch full = packer.Pack(changes, 3);
  ASSERT_EQ(full.keyframes.size(), 1u);
  EXPECT_FALSE(full.keyframes[0].anchor_only);
  EXPECT_EQ(full.keyframes[0].features->keypoints.size(), 200u);
  EXPECT_EQ(packer.anchors_sent(), 1u) << "first transmissions only";
  EXPECT_EQ(packer.anchors_resent_in_full(), 1u);
}

}  // namespace
}  // namespace ccm
