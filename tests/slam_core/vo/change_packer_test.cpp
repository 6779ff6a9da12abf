// ChangePacker with objects the server sent back (map sharing with
// share_own_keyframes_after_s): an agent's own old keyframes and points that return from the
// server are the server's already, so they never leave again, and new data that refers to
// them is not held back waiting for them to be sent.
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

}  // namespace
}  // namespace ccm
