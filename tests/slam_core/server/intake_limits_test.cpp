// The back-end's intake on real VO output (a hall3 excerpt): malformed items are counted and
// dropped while the rest is processed; agents, queues (batches and bytes) and map segments
// are bounded; and the map stack's bookkeeping of anchors and fusions.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "tests/slam_core/server/server_test_util.h"

namespace ccm {
namespace {

using testing::Hall3Stream;
using testing::SimVocabulary;

TEST(Submit, MalformedItemsAreCountedAndDroppedTheRestIsProcessed) {
  const testing::VoStream& s = Hall3Stream();
  AgentBatch b = s.batches.front();
  ASSERT_GE(b.keyframes.size(), 2u);
  KeyframeData& bad_index = b.keyframes[1];
  ASSERT_FALSE(bad_index.point_links.empty());
  bad_index.point_links.front().first = 100000;
  EXPECT_NE(ValidateKeyframeData(bad_index, 1).find("out of range"), std::string::npos);
  KeyframeData foreign = b.keyframes[0];
  foreign.id = KeyframeId::Make(7, 99);
  EXPECT_NE(ValidateKeyframeData(foreign, 1).find("belongs to agent 7"), std::string::npos);
  KeyframeData nan_pose = b.keyframes[0];
  nan_pose.pred_from_cam = SE3(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(NAN, 0, 0));
  EXPECT_NE(ValidateKeyframeData(nan_pose, 1).find("invalid pose"), std::string::npos);
  MapPointData bad_point = b.map_points.front();
  bad_point.position_ref.x() = INFINITY;
  b.map_points.push_back(bad_point);

  ServerBackend backend(SimVocabulary(), ServerOptions{});
  EXPECT_EQ(backend.Submit(b), 2);
  backend.ProcessAllQueued();
  const BackendStats st = backend.Status().stats;
  EXPECT_EQ(st.agents.at(1).rejected, 2);
  EXPECT_NE(st.agents.at(1).last_rejection.find("out of range"), std::string::npos);
  EXPECT_EQ(st.agents.at(1).keyframes_registered, static_cast<int64_t>(b.keyframes.size()) - 1);
}

TEST(Submit, AgentsBeyondMaxAgentsAreRefused) {
  const testing::VoStream& s = Hall3Stream();
  ServerOptions o;
  o.max_agents = 1;
  ServerBackend backend(SimVocabulary(), o);
  EXPECT_EQ(backend.Submit(s.batches.front()), 0);
  AgentBatch other;
  other.agent = 2;
  EXPECT_EQ(backend.Submit(other), -1);
  EXPECT_EQ(backend.Status().stats.batches_rejected, 1);
  EXPECT_EQ(backend.Status().agents.size(), 1u);
}

TEST(Submit, AFullAgentQueueDropsAndCountsInsteadOfGrowing) {
  const testing::VoStream& s = Hall3Stream();
  ServerOptions o;
  o.max_queued_batches_per_agent = 3;
  ServerBackend backend(SimVocabulary(), o);
  int refused = 0;
  for (const AgentBatch& b : s.batches) refused += backend.Submit(b) < 0;  // nobody processes
  EXPECT_EQ(refused, static_cast<int>(s.batches.size()) - 3);
  EXPECT_EQ(backend.Status().queues.agent_batches.at(1), 3u);
  EXPECT_EQ(backend.Status().stats.agents.at(1).batches_dropped, refused);
  backend.ProcessAllQueued();
  EXPECT_GT(backend.Snapshot().AgentTrajectory(1).size(), 0u) << "what was queued is processed";
}

TEST(Submit, AQueueIsBoundedInBytesAsWellAsInBatches) {
  // Few batches of many full keyframes: within the batch count, beyond the memory bound.
  const testing::VoStream& s = Hall3Stream();
  size_t total = 0;
  for (const AgentBatch& b : s.batches) total += ApproxBatchBytes(b);
  ASSERT_GT(total, size_t{2} << 20) << "hall3's 10 s should be a few MB of keyframes";
  ServerOptions o;
  o.max_queued_bytes_per_agent = size_t{1} << 20;
  ServerBackend backend(SimVocabulary(), o);
  int refused = 0;
  for (const AgentBatch& b : s.batches) refused += backend.Submit(b) < 0;  // nobody processes
  const QueueDepths d = backend.Status().queues;
  std::printf("  %zu batches, %.1f MB; queued %zu batches, %.2f MB; %d refused\n", s.batches.size(), total / 1e6,
              d.agent_batches.at(1), d.agent_bytes.at(1) / 1e6, refused);
  EXPECT_GT(refused, 0);
  EXPECT_LE(d.agent_bytes.at(1), o.max_queued_bytes_per_agent);
  EXPECT_EQ(d.agent_batches.at(1) + refused, s.batches.size());
  EXPECT_EQ(backend.Status().stats.agents.at(1).batches_dropped, refused);
  EXPECT_NE(backend.Status().stats.agents.at(1).last_rejection.find("max_queued_bytes_per_agent"), std::string::npos);
  backend.ProcessAllQueued();
  EXPECT_EQ(backend.Status().queues.agent_bytes.at(1), 0u) << "the count follows the queue down";
  // Processed, the queue takes batches again.
  EXPECT_EQ(backend.Submit(s.batches.back()), 0);
}

TEST(Submit, AnAgentCannotOpenMapSegmentsWithoutEnd) {
  // A batch whose points name one new segment each (a faulty or hostile agent) would make
  // one server map per segment; the budget refuses the batch that goes beyond it, whole.
  const testing::VoStream& s = Hall3Stream();
  ServerOptions o;
  o.max_segments_per_agent = 4;
  ServerBackend backend(SimVocabulary(), o);
  ASSERT_GE(s.batches.front().map_points.size(), 8u);
  AgentBatch flood;
  flood.agent = 1;
  flood.segment = MapId::Make(1, 900);
  for (size_t i = 0; i < 8; ++i) {
    MapPointData p = s.batches.front().map_points[i];
    p.segment = MapId::Make(1, 1000 + i);
    flood.map_points.push_back(p);
  }
  EXPECT_EQ(backend.Submit(flood), -1);
  EXPECT_EQ(backend.Status().stats.agents.at(1).segments_refused, 1);
  EXPECT_NE(backend.Status().stats.agents.at(1).last_rejection.find("max_segments_per_agent"), std::string::npos);
  // Within the budget: the agent's real stream (one segment) goes through, and so does a
  // batch naming three more; a fifth segment does not.
  for (const AgentBatch& b : s.batches) EXPECT_GE(backend.Submit(b), 0);
  flood.map_points.resize(3);
  flood.segment = flood.map_points.front().segment;
  EXPECT_EQ(backend.Submit(flood), 0);
  AgentBatch fifth;
  fifth.agent = 1;
  fifth.segment = MapId::Make(1, 2000);
  EXPECT_EQ(backend.Submit(fifth), -1);
  EXPECT_EQ(backend.Status().stats.agents.at(1).segments_refused, 2);
  backend.ProcessAllQueued();
  EXPECT_LE(backend.Snapshot().Summaries().size(), 4u);
  EXPECT_GT(backend.Snapshot().AgentTrajectory(1).size(), 10u);
}

TEST(ServerMap, AnchorOffsetsFollowAScaleCorrectionOfTheirRoot) {
  // Keyframe k1 (in the map) carries anchor a, which carries anchor b; k2 carries c. A Sim(3)
  // correction that scaled the map around k1 by 1.5 must stretch a's and b's offsets; c's
  // root did not change.
  ServerMap smap(MapId::Make(1, 1), MapOptions{});
  CameraIntrinsics intrinsics;
  intrinsics.type = CameraType::kPinholeRadTan;
  intrinsics.width_px = 752;
  intrinsics.height_px = 480;
  intrinsics.fx = intrinsics.fy = 458.0;
  intrinsics.cx = 376.0;
  intrinsics.cy = 240.0;
  intrinsics.distortion = {0.0, 0.0, 0.0, 0.0};
  std::shared_ptr<const CameraModel> camera(MakeCamera(intrinsics));
  const auto pyramid = std::make_shared<const ScalePyramid>(ScalePyramid::Make(8, 1.2));
  const KeyframeId k1 = KeyframeId::Make(1, 1), k2 = KeyframeId::Make(1, 2);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()));
  for (const auto& [id, x] : {std::pair{k1, 0.0}, std::pair{k2, 5.0}}) {
    smap.map().AddKeyframe(std::make_shared<KeyFrame>(id, 0, camera, std::make_shared<FrameFeatures>(), pyramid,
                                                      SE3(turn, Eigen::Vector3d(x, 1, 0))));
  }
  const KeyframeId a = KeyframeId::Make(1, 3), b = KeyframeId::Make(1, 4), c = KeyframeId::Make(1, 5);
  const SE3 a_off(Eigen::Quaterniond::Identity(), {0.1, 0.0, 0.05}), b_off(turn, {0.0, 0.2, 0.0});
  smap.AddAnchor(a, {k1, a_off, 0, MapId::Make(1, 1)});
  smap.AddAnchor(b, {a, b_off, 0, MapId::Make(1, 1)});
  smap.AddAnchor(c, {k2, a_off, 0, MapId::Make(1, 1)});
  smap.RescaleAnchors([&](KeyframeId root) { return root == k1 ? 1.5 : 1.0; });
  const SE3 w1 = *smap.PoseOf(k1), w2 = *smap.PoseOf(k2);
  const auto scaled = [](const SE3& T) { return SE3(T.rotation(), 1.5 * T.translation()); };
  EXPECT_LT((smap.PoseOf(a)->translation() - (w1 * scaled(a_off)).translation()).norm(), 1e-12);
  EXPECT_LT((smap.PoseOf(b)->translation() - (w1 * scaled(a_off) * scaled(b_off)).translation()).norm(), 1e-12);
  EXPECT_LT((smap.PoseOf(c)->translation() - (w2 * a_off).translation()).norm(), 1e-12);
  EXPECT_LT(smap.PoseOf(b)->rotation().angularDistance((w1 * a_off * b_off).rotation()), 1e-12);
}

TEST(MapStack, RepointComposesTheFusionSim3AndScale) {
  MapStack stack(MapOptions{});
  const MapId seg1 = MapId::Make(1, 1), seg2 = MapId::Make(2, 1);
  const auto m1 = stack.MapFor(1, seg1);
  const auto m2 = stack.MapFor(2, seg2);
  ASSERT_NE(m1->id(), m2->id());
  const Sim3 before(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 3));
  stack.EditHandler(2, seg2, [&](AgentHandler* h) {
    h->map_from_segment = before;
    h->scale = 0.8;
  });
  const Sim3 fusion(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(-0.5, Eigen::Vector3d::UnitX())), Eigen::Vector3d(-4, 0, 1));
  stack.Repoint(m2->id(), m1->id(), fusion);
  const auto h = stack.Handler(2, seg2);
  ASSERT_TRUE(h);
  EXPECT_EQ(h->map, m1->id());
  EXPECT_NEAR(h->scale, 1.6, 1e-12);
  const Eigen::Vector3d p(0.3, -1.0, 2.0);
  EXPECT_LT((h->map_from_segment * p - fusion * (before * p)).norm(), 1e-12);
  EXPECT_EQ(stack.GetMap(m2->id()), nullptr);
  EXPECT_EQ(stack.num_maps(), 1u);
  EXPECT_EQ(stack.MapFor(2, seg2)->id(), m1->id());
}

}  // namespace
}  // namespace ccm
