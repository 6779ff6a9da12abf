// AgentNeighbourhood, what the server sends an agent, on a hand-built fused map of two agents:
// which keyframes go (other agents' covisible ones, the agent's own only when old enough),
// that poses and points arrive in the reference keyframe's frame, that a point's observations
// name only keyframes the agent will have, and that keyframes erased while it runs (the
// redundancy step and other agents' server mapping erase under the shared structure lock)
// never crash it (a 6-agent fleet run did, 2026-11-29: a keyframe erased between its loops).
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <set>
#include <thread>
#include <vector>

#include "slam_core/server/outgoing.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

constexpr int kPointsPerKeyframe = 20;
constexpr int kSeenBy = 4;  // every point is observed by this many consecutive keyframes

// Keyframes alternate between agent 1 and agent 2 along x, 20 cm apart, one second apart,
// all in agent 1's first-segment map (as after a fusion); returns the keyframe ids in order.
std::vector<KeyframeId> BuildFusedMap(MapStack* stack, int keyframes) {
  const MapId segment = MapId::Make(1, 1);
  ServerMap& smap = *stack->MapFor(1, segment);
  Map& map = smap.map();
  const auto camera = testing::TestCamera();
  const auto pyramid = std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2));
  std::vector<KeyframeId> ids;
  std::vector<int> next_keypoint(keyframes, 0);
  for (int k = 0; k < keyframes; ++k) {
    auto f = std::make_shared<FrameFeatures>();
    for (int i = 0; i < kPointsPerKeyframe * kSeenBy; ++i) {
      Keypoint kp;
      kp.u = static_cast<float>(10 + (i * 37) % 700);
      kp.v = static_cast<float>(10 + (i * 53) % 460);
      f->keypoints.push_back(kp);
      f->descriptors.push_back(OrbDescriptor{});
    }
    const AgentId agent = k % 2 == 0 ? 1 : 2;
    const KeyframeId id = KeyframeId::Make(agent, k / 2 + 1);
    map.AddKeyframe(std::make_shared<KeyFrame>(id, int64_t{1000000000} * (k + 1), camera, f, pyramid,
                                               SE3(Eigen::Quaterniond::Identity(), {0.2 * k, 0, 0})));
    if (agent == 1) {
      ServerKeyframeInfo info;
      info.segment = segment;
      smap.SetInfo(id, info);
    }
    ids.push_back(id);
  }
  uint64_t point = 0;
  for (int first = 0; first + kSeenBy <= keyframes; ++first) {
    for (int p = 0; p < kPointsPerKeyframe; ++p) {
      const MapPointId mp = MapPointId::Make(1, ++point);
      map.AddMapPoint(std::make_shared<MapPoint>(mp, Eigen::Vector3d(0.2 * first + 0.01 * p, 0.5, 5), ids[first],
                                                 OrbDescriptor{}));
      for (int k = first; k < first + kSeenBy; ++k) map.AddObservation(ids[k], next_keypoint[k]++, mp);
    }
  }
  for (const KeyframeId id : ids) map.UpdateConnections(id);
  return ids;
}

// The keyframes of `agent` in a neighbourhood, in the order sent.
std::vector<KeyframeId> KeyframesOf(const ServerMapData& data, AgentId agent) {
  std::vector<KeyframeId> ids;
  for (const ServerKeyframe& skf : data.keyframes) {
    if (skf.id.agent() == agent) ids.push_back(skf.id);
  }
  return ids;
}

TEST(AgentNeighbourhood, SendsOtherAgentsCovisibleKeyframesAndTheirPointsInTheReferenceFrame) {
  MapStack stack{MapOptions{}};
  const auto ids = BuildFusedMap(&stack, 12);
  const KeyframeId reference = ids[10];  // agent 1's newest
  ASSERT_EQ(reference.agent(), 1);
  NeighbourhoodOptions options;
  options.keyframes = 3;
  const auto data = AgentNeighbourhood(stack, 1, reference, options);
  ASSERT_TRUE(data.has_value());
  EXPECT_EQ(data->reference_kf, reference);
  ASSERT_FALSE(data->keyframes.empty());
  EXPECT_LE(data->keyframes.size(), 3u);
  const Map& map = stack.MapHolding(reference)->map();
  const SE3 ref_from_world = map.keyframe(reference)->world_from_cam().inverse();
  std::set<KeyframeId> sent;
  for (const ServerKeyframe& skf : data->keyframes) {
    EXPECT_EQ(skf.id.agent(), 2) << "agent 1 made its own recent keyframes: none go back";
    const auto kf = map.keyframe(skf.id);
    ASSERT_TRUE(kf);
    EXPECT_LT((skf.ref_from_cam.translation() - (ref_from_world * kf->world_from_cam()).translation()).norm(), 1e-9);
    sent.insert(skf.id);
  }
  ASSERT_FALSE(data->map_points.empty());
  for (const ServerMapPoint& p : data->map_points) {
    const auto mp = map.map_point(p.id);
    ASSERT_TRUE(mp);
    EXPECT_LT((p.position_ref - ref_from_world * mp->position()).norm(), 1e-9);
    ASSERT_FALSE(p.observations.empty());
    for (const auto& [kf, idx] : p.observations) {
      EXPECT_TRUE(sent.count(kf) || kf.agent() == 1) << "observation by a keyframe the agent will not have";
    }
  }
}

TEST(AgentNeighbourhood, KeyframesTheAgentHoldsGoAsPosesOnlyWithTheirPoints) {
  MapStack stack{MapOptions{}};
  const auto ids = BuildFusedMap(&stack, 12);
  NeighbourhoodOptions options;
  options.keyframes = 3;
  const auto all = AgentNeighbourhood(stack, 1, ids[10], options);
  ASSERT_TRUE(all.has_value());
  ASSERT_GE(all->keyframes.size(), 2u);
  const std::unordered_set<KeyframeId> held = {all->keyframes[0].id};
  const auto delta = AgentNeighbourhood(stack, 1, ids[10], options, &held);
  ASSERT_TRUE(delta.has_value());
  ASSERT_EQ(delta->keyframes.size(), all->keyframes.size()) << "the same neighbourhood, only cheaper";
  for (size_t i = 0; i < delta->keyframes.size(); ++i) {
    const ServerKeyframe& k = delta->keyframes[i];
    EXPECT_EQ(k.id, all->keyframes[i].id);
    EXPECT_EQ(k.held, held.count(k.id) > 0);
    EXPECT_EQ(k.features == nullptr, k.held);
    EXPECT_EQ(k.camera == nullptr, k.held);
    EXPECT_LT((k.ref_from_cam.translation() - all->keyframes[i].ref_from_cam.translation()).norm(), 1e-12);
  }
  EXPECT_EQ(delta->map_points.size(), all->map_points.size()) << "points follow corrections: they still go";
}

TEST(AgentNeighbourhood, SendsTheAgentsOwnKeyframesOnlyWhenOlderThanAsked) {
  MapStack stack{MapOptions{}};
  const auto ids = BuildFusedMap(&stack, 12);
  NeighbourhoodOptions options;
  options.keyframes = 8;
  // Stamps are 1 s apart, a keyframe is covisible with 3 on each side: of agent 1's, ids[8]
  // (2 s older) qualifies, ids[12] (newer) does not.
  options.own_keyframes_after_s = 1.5;
  options.own_nearby_depth_ratio = 0.0;  // covisible ones only
  const auto data = AgentNeighbourhood(stack, 1, ids[10], options);
  ASSERT_TRUE(data.has_value());
  EXPECT_EQ(KeyframesOf(*data, 1), (std::vector<KeyframeId>{ids[8]}));
}

TEST(AgentNeighbourhood, AnAnchorReferenceCountsAgeFromItsOwnStampAndSendsItsBaseFirst) {
  // An agent back at a place it flew 20 s ago: its new keyframe left as an anchor of the first
  // pass's ids[2] (agent 1, 3 s). Age counts from the anchor (22 s), so the first pass's
  // keyframes are old, and the base, the nearest of all, goes first (2026-11-29: age counted from
  // the base made every revisit's neighbourhood empty).
  MapStack stack{MapOptions{}};
  const auto ids = BuildFusedMap(&stack, 12);
  ServerMap& smap = *stack.MapHolding(ids[2]);
  const KeyframeId anchor = KeyframeId::Make(1, 50);
  smap.AddAnchor(anchor, KeyframeAnchor{ids[2], SE3(Eigen::Quaterniond::Identity(), {0.05, 0, 0}),
                                        int64_t{22000000000}, MapId::Make(1, 1)});
  NeighbourhoodOptions options;
  options.keyframes = 4;
  options.own_keyframes_after_s = 10.0;
  const auto data = AgentNeighbourhood(stack, 1, anchor, options);
  ASSERT_TRUE(data.has_value());
  ASSERT_FALSE(data->keyframes.empty());
  EXPECT_EQ(data->keyframes[0].id, ids[2]);
  EXPECT_GE(KeyframesOf(*data, 1).size(), 2u) << "the base and its covisible first-pass keyframes of agent 1";
  EXPECT_LT((data->keyframes[0].ref_from_cam.translation() - Eigen::Vector3d(-0.05, 0, 0)).norm(), 1e-9);
  // Counted from the base's stamp (3 s) nothing of agent 1 would be old.
  options.own_keyframes_after_s = 25.0;
  const auto young = AgentNeighbourhood(stack, 1, anchor, options);
  ASSERT_TRUE(young.has_value());
  EXPECT_TRUE(KeyframesOf(*young, 1).empty());
}

TEST(AgentNeighbourhood, FillsWithTheAgentsOwnOldKeyframesNearTheReferenceNearestFirst) {
  MapStack stack{MapOptions{}};
  const auto ids = BuildFusedMap(&stack, 12);
  NeighbourhoodOptions options;
  options.keyframes = 12;
  options.own_keyframes_after_s = 1.5;
  // The reference ids[10] sits at x = 2.0 m looking at points 5 m away; agent 1's older
  // keyframes sit at x = 1.6 (covisible), 1.2, 0.8, 0.4 and 0 m. A radius of 0.18 x 5 m = 0.9 m
  // takes 1.2 m (0.8 m away) and leaves 0.8 m (1.2 m away).
  options.own_nearby_depth_ratio = 0.18;
  auto data = AgentNeighbourhood(stack, 1, ids[10], options);
  ASSERT_TRUE(data.has_value());
  EXPECT_EQ(KeyframesOf(*data, 1), (std::vector<KeyframeId>{ids[8], ids[6]}));
  // A radius over the whole row: all, the covisible one first, then nearest first; recent
  // ones (within 1.5 s) never.
  options.own_nearby_depth_ratio = 1.0;
  data = AgentNeighbourhood(stack, 1, ids[10], options);
  ASSERT_TRUE(data.has_value());
  EXPECT_EQ(KeyframesOf(*data, 1), (std::vector<KeyframeId>{ids[8], ids[6], ids[4], ids[2], ids[0]}));
  // Their points go along: the first keyframe's points are seen by no one covisible with ids[10].
  const Map& map = stack.MapHolding(ids[10])->map();
  bool first_points_sent = false;
  for (const ServerMapPoint& p : data->map_points) {
    first_points_sent |= map.map_point(p.id)->reference_kf() == ids[0];
  }
  EXPECT_TRUE(first_points_sent);
  // The whole budget taken by covisible keyframes: nothing added for nearness.
  options.keyframes = 2;
  data = AgentNeighbourhood(stack, 1, ids[10], options);
  ASSERT_TRUE(data.has_value());
  EXPECT_EQ(data->keyframes.size(), 2u);
}

TEST(AgentNeighbourhood, KeyframesErasedWhileItRunsAreLeftOutNotDereferenced) {
  for (int round = 0; round < 20; ++round) {
    MapStack stack{MapOptions{}};
    const auto ids = BuildFusedMap(&stack, 16);
    const auto smap = stack.MapHolding(ids[14]);
    std::atomic<bool> done{false};
    // What the redundancy step does: erase under the shared structure lock.
    std::thread eraser([&] {
      for (const KeyframeId id : ids) {
        if (id.agent() != 2) continue;
        std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
        smap->map().EraseKeyframe(id);
        std::this_thread::yield();
      }
      done = true;
    });
    NeighbourhoodOptions options;
    options.keyframes = 4;
    while (!done) {
      const auto data = AgentNeighbourhood(stack, 1, ids[14], options);
      if (!data) continue;
      std::set<KeyframeId> sent;
      for (const ServerKeyframe& skf : data->keyframes) sent.insert(skf.id);
      for (const ServerMapPoint& p : data->map_points) {
        for (const auto& [kf, idx] : p.observations) ASSERT_TRUE(sent.count(kf) || kf.agent() == 1);
      }
    }
    eraser.join();
    EXPECT_FALSE(AgentNeighbourhood(stack, 1, ids[14], options).has_value())
        << "agent 2's keyframes are all gone: nothing left to send";
  }
}

}  // namespace
}  // namespace ccm
