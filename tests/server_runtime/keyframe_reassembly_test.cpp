// KeyframeReassembly (server_runtime/keyframe_reassembly.h): what the server's intake does
// with data that arrives incomplete, out of order, early, twice or floods it. Time is
// passed in, so the hold rules are tested without sleeping.
#include "server_runtime/keyframe_reassembly.h"

#include <gtest/gtest.h>

namespace ccm::server {
namespace {

using Clock = KeyframeReassembly::Clock;
using Fate = KeyframeReassembly::UpdateFate;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr AgentId kAgent = 1;
const MapId kSegment = MapId::Make(kAgent, 1);

KeyframeData Keyframe(AgentId agent, uint64_t counter, std::vector<MapPointId> points) {
  KeyframeData kf;
  kf.id = KeyframeId::Make(agent, counter);
  kf.segment = MapId::Make(agent, 1);
  for (size_t i = 0; i < points.size(); ++i) kf.point_links.emplace_back(static_cast<int>(i), points[i]);
  return kf;
}

MapPointData Point(AgentId agent, uint64_t counter) {
  MapPointData p;
  p.id = MapPointId::Make(agent, counter);
  p.segment = MapId::Make(agent, 1);
  p.position_ref = Eigen::Vector3d(0, 0, 1);
  return p;
}

KeyframePoseUpdate PoseUpdate(AgentId agent, uint64_t counter, double x) {
  KeyframePoseUpdate u;
  u.id = KeyframeId::Make(agent, counter);
  u.segment = MapId::Make(agent, 1);
  u.pred_from_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, 0, 0));
  return u;
}

/// Every keyframe id in the batches, in submission order.
std::vector<KeyframeId> KeyframesIn(BatchSet* set) {
  std::vector<KeyframeId> ids;
  for (const AgentBatch& b : set->Take()) {
    for (const KeyframeData& kf : b.keyframes) ids.push_back(kf.id);
  }
  return ids;
}

TEST(KeyframeReassembly, KeyframeWaitsUntilEveryOwnPointArrived) {
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  r.AddKeyframe(kAgent, Keyframe(kAgent, 5, {MapPointId::Make(kAgent, 1), MapPointId::Make(kAgent, 2)}),
                KeyframeId::Make(kAgent, 5), t0);
  EXPECT_TRUE(r.Release(t0, &out).empty());
  EXPECT_TRUE(KeyframesIn(&out).empty());
  r.AddMapPoint(kAgent, Point(kAgent, 1), t0 + milliseconds(10), &out);
  r.Release(t0 + milliseconds(10), &out);
  std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);  // the point went out at once, the keyframe still waits
  EXPECT_EQ(batches[0].map_points.size(), 1u);
  EXPECT_TRUE(batches[0].keyframes.empty());
  EXPECT_EQ(r.held(), 1u);

  r.AddMapPoint(kAgent, Point(kAgent, 2), t0 + milliseconds(20), &out);
  EXPECT_TRUE(r.Release(t0 + milliseconds(20), &out).empty());  // complete: none incomplete
  batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframes.size(), 1u);
  EXPECT_EQ(batches[0].keyframes[0].id, KeyframeId::Make(kAgent, 5));
  EXPECT_FALSE(batches[0].keyframes[0].points_incomplete);
  EXPECT_EQ(batches[0].reference_kf, KeyframeId::Make(kAgent, 5));
  EXPECT_EQ(batches[0].map_points.size(), 1u);
  EXPECT_EQ(r.held(), 0u);
}

TEST(KeyframeReassembly, MissingPointsReleaseTheKeyframeAfterTheHoldAndAreCounted) {
  ReassemblyOptions o;
  o.max_keyframe_hold = milliseconds(1500);
  KeyframeReassembly r(o);
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  EXPECT_FALSE(r.NextDeadline().has_value());
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {MapPointId::Make(kAgent, 9)}), KeyframeId(), t0);
  ASSERT_TRUE(r.NextDeadline().has_value());
  EXPECT_EQ(*r.NextDeadline(), t0 + milliseconds(1500));
  EXPECT_TRUE(r.Release(t0 + milliseconds(1499), &out).empty());
  EXPECT_TRUE(KeyframesIn(&out).empty());
  const auto incomplete = r.Release(t0 + milliseconds(1500), &out);
  ASSERT_EQ(incomplete.count(kAgent), 1u);
  EXPECT_EQ(incomplete.at(kAgent), 1);
  const std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframes.size(), 1u);
  EXPECT_EQ(batches[0].keyframes[0].id, KeyframeId::Make(kAgent, 1));
  // Flagged, so the back-end maps and queries it only once its points came (registration.h).
  EXPECT_TRUE(batches[0].keyframes[0].points_incomplete);
  EXPECT_FALSE(r.NextDeadline().has_value());
}

TEST(KeyframeReassembly, AnAgentsKeyframesLeaveInArrivalOrderOtherAgentsAreNotBlocked) {
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {MapPointId::Make(kAgent, 7)}), KeyframeId(), t0);
  r.AddKeyframe(kAgent, Keyframe(kAgent, 2, {}), KeyframeId(), t0);  // complete, but behind 1
  r.AddKeyframe(2, Keyframe(2, 1, {}), KeyframeId(), t0);
  r.Release(t0, &out);
  EXPECT_EQ(KeyframesIn(&out), std::vector<KeyframeId>{KeyframeId::Make(2, 1)});
  r.AddMapPoint(kAgent, Point(kAgent, 7), t0, &out);
  r.Release(t0, &out);
  EXPECT_EQ(KeyframesIn(&out), (std::vector<KeyframeId>{KeyframeId::Make(kAgent, 1), KeyframeId::Make(kAgent, 2)}));
}

TEST(KeyframeReassembly, PointsOfOtherAgentsDoNotHoldAKeyframe) {
  // Points the server shared from other agents are on the server already.
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {MapPointId::Make(3, 40)}), KeyframeId(), t0);
  r.Release(t0, &out);
  EXPECT_EQ(KeyframesIn(&out), std::vector<KeyframeId>{KeyframeId::Make(kAgent, 1)});
}

TEST(KeyframeReassembly, AnUpdateThatOvertookItsKeyframeIsAppliedWhenTheKeyframeArrives) {
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  EXPECT_EQ(r.AddKeyframeUpdate(kAgent, PoseUpdate(kAgent, 4, 1.0), &out), Fate::kKeptEarly);
  EXPECT_EQ(r.AddKeyframeUpdate(kAgent, PoseUpdate(kAgent, 4, 2.0), &out), Fate::kKeptEarly);  // latest wins
  EXPECT_TRUE(out.empty());
  r.AddKeyframe(kAgent, Keyframe(kAgent, 4, {}), KeyframeId(), t0);
  r.Release(t0, &out);
  const std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframes.size(), 1u);
  EXPECT_DOUBLE_EQ(batches[0].keyframes[0].pred_from_cam.translation().x(), 2.0);
  EXPECT_TRUE(batches[0].keyframe_updates.empty());
}

TEST(KeyframeReassembly, AnUpdateForAHeldKeyframeChangesItAndOneForASubmittedKeyframeIsBatched) {
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {MapPointId::Make(kAgent, 1)}), KeyframeId(), t0);
  EXPECT_EQ(r.AddKeyframeUpdate(kAgent, PoseUpdate(kAgent, 1, 3.0), &out), Fate::kAppliedToHeld);
  EXPECT_TRUE(out.empty());
  r.AddMapPoint(kAgent, Point(kAgent, 1), t0, &out);
  r.Release(t0, &out);
  std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframes.size(), 1u);
  EXPECT_DOUBLE_EQ(batches[0].keyframes[0].pred_from_cam.translation().x(), 3.0);

  EXPECT_EQ(r.AddKeyframeUpdate(kAgent, PoseUpdate(kAgent, 1, 4.0), &out), Fate::kBatched);
  batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframe_updates.size(), 1u);
  EXPECT_DOUBLE_EQ(batches[0].keyframe_updates[0].pred_from_cam.translation().x(), 4.0);
}

TEST(KeyframeReassembly, AnOvertakingPointUpdateIsAppliedWhenThePointArrives) {
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  MapPointPositionUpdate u;
  u.id = MapPointId::Make(kAgent, 3);
  u.reference_kf = KeyframeId::Make(kAgent, 8);
  u.position_ref = Eigen::Vector3d(1, 2, 3);
  EXPECT_EQ(r.AddMapPointUpdate(kAgent, u, kSegment, &out), Fate::kKeptEarly);
  r.AddMapPoint(kAgent, Point(kAgent, 3), t0, &out);
  std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].map_points.size(), 1u);
  EXPECT_EQ(batches[0].map_points[0].reference_kf, KeyframeId::Make(kAgent, 8));
  EXPECT_EQ(batches[0].map_points[0].position_ref, Eigen::Vector3d(1, 2, 3));
  EXPECT_TRUE(batches[0].map_point_updates.empty());
  // Later updates of a point the server has go out as updates.
  EXPECT_EQ(r.AddMapPointUpdate(kAgent, u, kSegment, &out), Fate::kBatched);
  batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  EXPECT_EQ(batches[0].map_point_updates.size(), 1u);
}

TEST(KeyframeReassembly, AResendOfAHeldKeyframeReplacesItInItsPlace) {
  KeyframeReassembly r;
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {MapPointId::Make(kAgent, 1)}), KeyframeId(), t0);
  r.AddKeyframe(kAgent, Keyframe(kAgent, 2, {}), KeyframeId(), t0);
  KeyframeData resent = Keyframe(kAgent, 1, {MapPointId::Make(kAgent, 1)});
  resent.stamp_ns = 42;
  r.AddKeyframe(kAgent, resent, KeyframeId::Make(kAgent, 2), t0 + milliseconds(500));
  EXPECT_EQ(r.held(), 2u);
  // The resend does not restart the hold: the original's deadline stands.
  EXPECT_EQ(*r.NextDeadline(), t0 + milliseconds(1500));
  r.AddMapPoint(kAgent, Point(kAgent, 1), t0, &out);
  r.Release(t0 + milliseconds(600), &out);
  const std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframes.size(), 2u);
  EXPECT_EQ(batches[0].keyframes[0].id, KeyframeId::Make(kAgent, 1));
  EXPECT_EQ(batches[0].keyframes[0].stamp_ns, 42);
  EXPECT_EQ(batches[0].keyframes[1].id, KeyframeId::Make(kAgent, 2));
  EXPECT_EQ(batches[0].reference_kf, KeyframeId::Make(kAgent, 2));
}

TEST(KeyframeReassembly, PointsForgottenAfterTheWindowStillCountAsArrived) {
  ReassemblyOptions o;
  o.seen_window = seconds(120);
  KeyframeReassembly r(o);
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  r.AddMapPoint(kAgent, Point(kAgent, 10), t0, &out);
  r.AddMapPoint(kAgent, Point(kAgent, 500), t0 + seconds(121), &out);  // prunes point 10
  // Point 3 never came, but ids up to the newest forgotten one (10) count as arrived.
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {MapPointId::Make(kAgent, 10), MapPointId::Make(kAgent, 3)}),
                KeyframeId(), t0 + seconds(121));
  r.AddKeyframe(2, Keyframe(2, 1, {MapPointId::Make(2, 11)}), KeyframeId(), t0 + seconds(121));
  r.Release(t0 + seconds(121), &out);
  EXPECT_EQ(KeyframesIn(&out), std::vector<KeyframeId>{KeyframeId::Make(kAgent, 1)});
  EXPECT_EQ(r.held(), 1u);  // agent 2's point 11 is unknown: it waits
}

TEST(KeyframeReassembly, AFloodOfUpdatesForUnknownIdsIsBounded) {
  ReassemblyOptions o;
  o.max_early_updates = 4;
  KeyframeReassembly r(o);
  const Clock::time_point t0 = Clock::now();
  BatchSet out;
  for (uint64_t c = 1; c <= 5; ++c) EXPECT_EQ(r.AddKeyframeUpdate(kAgent, PoseUpdate(kAgent, c, 7.0), &out), Fate::kKeptEarly);
  // The fifth cleared the first four: keyframe 1 arrives without its update, 5 with it.
  r.AddKeyframe(kAgent, Keyframe(kAgent, 1, {}), KeyframeId(), t0);
  r.AddKeyframe(kAgent, Keyframe(kAgent, 5, {}), KeyframeId(), t0);
  r.Release(t0, &out);
  const std::vector<AgentBatch> batches = out.Take();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].keyframes.size(), 2u);
  EXPECT_DOUBLE_EQ(batches[0].keyframes[0].pred_from_cam.translation().x(), 0.0);
  EXPECT_DOUBLE_EQ(batches[0].keyframes[1].pred_from_cam.translation().x(), 7.0);
}

TEST(KeyframeReassembly, BatchesAreOnePerAgentAndSegmentInOrder) {
  BatchSet set;
  set.For(2, MapId::Make(2, 1)).map_points.push_back(Point(2, 1));
  set.For(1, MapId::Make(1, 2)).map_points.push_back(Point(1, 1));
  set.For(1, MapId::Make(1, 1)).map_points.push_back(Point(1, 2));
  set.For(1, MapId::Make(1, 2)).map_points.push_back(Point(1, 3));
  const std::vector<AgentBatch> batches = set.Take();
  ASSERT_EQ(batches.size(), 3u);
  EXPECT_EQ(batches[0].segment, MapId::Make(1, 1));
  EXPECT_EQ(batches[1].segment, MapId::Make(1, 2));
  EXPECT_EQ(batches[1].map_points.size(), 2u);
  EXPECT_EQ(batches[2].agent, 2u);
  EXPECT_TRUE(set.empty());
}

}  // namespace
}  // namespace ccm::server
