// RecordedDataSource (ccm_fleet's agents): recorded batches leave at their recorded pace,
// one segment per batch, resends come from what was played, and RemapAgents renames every
// id of the agents it is given and no other.
#include <gtest/gtest.h>

#include "agent_runtime/recorded_data_source.h"

namespace ccm::agent {
namespace {

using Clock = RecordedDataSource::Clock;
constexpr int64_t kSecond = 1'000'000'000;

KeyframeData Keyframe(AgentId agent, uint64_t n, MapId segment) {
  KeyframeData k;
  k.id = KeyframeId::Make(agent, n);
  k.segment = segment;
  k.predecessor = n > 1 ? KeyframeId::Make(agent, n - 1) : KeyframeId::Invalid();
  return k;
}

// Batch i of agent 1 at `stamp_ns`, holding keyframe i + 1 and one point, in `segment`.
AgentBatch Batch(uint64_t i, int64_t stamp_ns, MapId segment) {
  AgentBatch b;
  b.agent = 1;
  b.segment = segment;
  b.stamp_ns = stamp_ns;
  b.keyframes.push_back(Keyframe(1, i + 1, segment));
  b.reference_kf = b.keyframes.back().id;
  MapPointData p;
  p.id = MapPointId::Make(1, i + 1);
  p.segment = segment;
  p.reference_kf = b.reference_kf;
  b.map_points.push_back(p);
  return b;
}

std::vector<AgentBatch> ThreeBatches(MapId second_segment = MapId::Make(1, 1)) {
  const int64_t t0 = 100 * kSecond;  // recordings start at their first frame's stamp
  return {Batch(0, t0, MapId::Make(1, 1)), Batch(1, t0 + kSecond, second_segment),
          Batch(2, t0 + 2 * kSecond, second_segment)};
}

std::chrono::steady_clock::duration Seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

TEST(RecordedDataSource, PlaysEachBatchOnceAtItsRecordedTime) {
  RecordedDataSource source(ThreeBatches(), 100 * kSecond, Clock::now() - Seconds(1.5), 1.0);
  const AgentBatch first = source.TakeBatch(0, false);
  ASSERT_EQ(first.keyframes.size(), 2u);  // recorded at 0 and 1 s, both due at 1.5 s
  EXPECT_EQ(first.keyframes[0].id, KeyframeId::Make(1, 1));
  EXPECT_EQ(first.keyframes[1].id, KeyframeId::Make(1, 2));
  EXPECT_EQ(first.map_points.size(), 2u);
  EXPECT_EQ(first.reference_kf, KeyframeId::Make(1, 2));  // the newest batch's
  EXPECT_EQ(first.stamp_ns, 101 * kSecond);
  EXPECT_FALSE(source.finished());
  EXPECT_EQ(source.counters().deferred, 1u);  // the 2 s batch: AgentComm is not drained yet
  EXPECT_TRUE(source.TakeBatch(0, false).empty());  // nothing new is due yet
  EXPECT_EQ(source.counters().keyframes_created, 2);
  EXPECT_DOUBLE_EQ(source.duration_s(), 2.0);
}

TEST(RecordedDataSource, SpeedScalesThePace) {
  // 0.6 s of wall time at 2x is 1.2 s of recording: the batches at 0 and 1 s, not 2 s.
  RecordedDataSource source(ThreeBatches(), 100 * kSecond, Clock::now() - Seconds(0.6), 2.0);
  EXPECT_EQ(source.TakeBatch(0, false).keyframes.size(), 2u);
  EXPECT_FALSE(source.finished());
  RecordedDataSource late(ThreeBatches(), 100 * kSecond, Clock::now() - Seconds(10), 1.0);
  EXPECT_EQ(late.TakeBatch(0, false).keyframes.size(), 3u);
  EXPECT_TRUE(late.finished());
  EXPECT_EQ(late.counters().deferred, 0u);
}

TEST(RecordedDataSource, ANewSegmentWaitsForTheNextBatch) {
  // Point updates carry their batch's segment: batches of two segments are never merged.
  const MapId second = MapId::Make(1, 2);
  RecordedDataSource source(ThreeBatches(second), 100 * kSecond, Clock::now() - Seconds(10), 1.0);
  const AgentBatch a = source.TakeBatch(0, false);
  ASSERT_EQ(a.keyframes.size(), 1u);
  EXPECT_EQ(a.segment, MapId::Make(1, 1));
  const AgentBatch b = source.TakeBatch(0, false);
  ASSERT_EQ(b.keyframes.size(), 2u);
  EXPECT_EQ(b.segment, second);
  EXPECT_TRUE(source.finished());
}

TEST(RecordedDataSource, ResendsWhatItPlayedInFrontOfTheNextBatch) {
  RecordedDataSource source(ThreeBatches(), 100 * kSecond, Clock::now() - Seconds(1.5), 1.0);
  EXPECT_FALSE(source.Resend(KeyframeId::Make(1, 3)));  // not played yet: the source cannot have sent it
  ASSERT_EQ(source.TakeBatch(0, false).keyframes.size(), 2u);
  EXPECT_TRUE(source.Resend(KeyframeId::Make(1, 1)));
  EXPECT_TRUE(source.Resend(KeyframeId::Make(1, 1)));  // asked twice, sent once
  EXPECT_FALSE(source.Resend(KeyframeId::Make(2, 1)));
  const AgentBatch again = source.TakeBatch(0, false);
  ASSERT_EQ(again.keyframes.size(), 1u);
  EXPECT_EQ(again.keyframes[0].id, KeyframeId::Make(1, 1));
  EXPECT_EQ(again.keyframes[0].segment, MapId::Make(1, 1));
  EXPECT_EQ(again.agent, 1);
  EXPECT_TRUE(source.TakeBatch(0, false).empty());
  EXPECT_EQ(source.counters().keyframes_created, 2);  // resends are not new keyframes
}

TEST(RecordedDataSource, CountsTheServersMapData) {
  RecordedDataSource source(ThreeBatches(), 100 * kSecond, Clock::now(), 1.0);
  ServerMapData data;
  data.keyframes.resize(3);
  data.map_points.resize(40);
  source.ApplyServerData(data);
  source.ApplyServerData(data);
  EXPECT_EQ(source.server_keyframes_received(), 6u);
  EXPECT_EQ(source.server_points_received(), 80u);
}

TEST(RemapAgents, RenamesEveryIdOfTheGivenAgentsAndNoOther) {
  const MapId segment = MapId::Make(1, 7);
  AgentBatch b = Batch(4, 0, segment);
  b.keyframes[0].parent = KeyframeId::Make(2, 9);                       // another agent's, shared
  b.keyframes[0].point_links = {{0, MapPointId::Make(1, 3)}, {1, MapPointId::Make(2, 4)}};
  b.map_points[0].observations = {{KeyframeId::Make(1, 2), 5}};
  b.keyframe_updates.push_back({KeyframeId::Make(1, 2), segment, KeyframeId::Make(1, 1), SE3(),
                                KeyframeId::Make(0, 3), SE3()});      // a server-side parent
  b.map_point_updates.push_back({MapPointId::Make(1, 8), KeyframeId::Make(1, 2), Eigen::Vector3d::Zero()});
  RemapAgents({{1, 11}}, &b);
  EXPECT_EQ(b.agent, 11);
  EXPECT_EQ(b.segment, MapId::Make(11, 7));
  EXPECT_EQ(b.reference_kf, KeyframeId::Make(11, 5));
  const KeyframeData& k = b.keyframes[0];
  EXPECT_EQ(k.id, KeyframeId::Make(11, 5));
  EXPECT_EQ(k.segment, MapId::Make(11, 7));
  EXPECT_EQ(k.predecessor, KeyframeId::Make(11, 4));
  EXPECT_EQ(k.parent, KeyframeId::Make(2, 9));
  EXPECT_EQ(k.point_links[0].second, MapPointId::Make(11, 3));
  EXPECT_EQ(k.point_links[1].second, MapPointId::Make(2, 4));
  EXPECT_EQ(b.map_points[0].id, MapPointId::Make(11, 5));
  EXPECT_EQ(b.map_points[0].segment, MapId::Make(11, 7));
  EXPECT_EQ(b.map_points[0].reference_kf, KeyframeId::Make(11, 5));
  EXPECT_EQ(b.map_points[0].observations[0].first, KeyframeId::Make(11, 2));
  EXPECT_EQ(b.keyframe_updates[0].id, KeyframeId::Make(11, 2));
  EXPECT_EQ(b.keyframe_updates[0].segment, MapId::Make(11, 7));
  EXPECT_EQ(b.keyframe_updates[0].predecessor, KeyframeId::Make(11, 1));
  EXPECT_EQ(b.keyframe_updates[0].parent, KeyframeId::Make(0, 3));
  EXPECT_EQ(b.map_point_updates[0].id, MapPointId::Make(11, 8));
  EXPECT_EQ(b.map_point_updates[0].reference_kf, KeyframeId::Make(11, 2));
  KeyframeData first = Keyframe(1, 1, segment);  // no predecessor: Invalid stays Invalid
  AgentBatch c;
  c.keyframes.push_back(first);
  RemapAgents({{1, 11}}, &c);
  EXPECT_FALSE(c.keyframes[0].predecessor.valid());
}

}  // namespace
}  // namespace ccm::agent
