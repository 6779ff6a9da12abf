// RedundancyStage on hand-built maps: which map it thins (large enough ones, in turn), what it
// never removes (a map's oldest keyframe, a handler's newest), that removed keyframes stay
// as anchors and are reported, and that keyframes whose points too few others see stay.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <set>
#include <vector>

#include "slam_core/server/redundancy.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

// `keyframes` keyframes of `agent` in its first segment's map, 20 cm apart; every point is
// observed by `seen_by` consecutive keyframes (all at pyramid level 0), so a keyframe's
// points are seen by seen_by - 1 others. The handler's newest keyframe is the last one.
std::shared_ptr<ServerMap> BuildMap(MapStack* stack, AgentId agent, int keyframes, int seen_by) {
  const MapId segment = MapId::Make(agent, 1);
  auto smap = stack->MapFor(agent, segment);
  Map& map = smap->map();
  const auto camera = testing::TestCamera();
  const auto pyramid = std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2));
  constexpr int kPointsPerKeyframe = 30;
  std::vector<KeyframeId> ids;
  std::vector<int> next_keypoint;
  for (int k = 0; k < keyframes; ++k) {
    auto f = std::make_shared<FrameFeatures>();
    for (int i = 0; i < kPointsPerKeyframe * seen_by; ++i) {
      Keypoint kp;
      kp.u = static_cast<float>(10 + (i * 37) % 700);
      kp.v = static_cast<float>(10 + (i * 53) % 460);
      f->keypoints.push_back(kp);
      f->descriptors.push_back(OrbDescriptor{});
    }
    const KeyframeId id = KeyframeId::Make(agent, k + 1);
    map.AddKeyframe(std::make_shared<KeyFrame>(id, int64_t{50000000} * (k + 1), camera, f, pyramid,
                                               SE3(Eigen::Quaterniond::Identity(), {0.2 * k, 0, 0})));
    ids.push_back(id);
    next_keypoint.push_back(0);
  }
  uint64_t point = 0;
  for (int first = 0; first + seen_by <= keyframes; ++first) {
    for (int p = 0; p < kPointsPerKeyframe; ++p) {
      const MapPointId mp = MapPointId::Make(agent, ++point);
      map.AddMapPoint(std::make_shared<MapPoint>(mp, Eigen::Vector3d(0.2 * first + 0.01 * p, 0.5, 5), ids[first],
                                                 OrbDescriptor{}));
      for (int k = first; k < first + seen_by; ++k) map.AddObservation(ids[k], next_keypoint[k]++, mp);
    }
  }
  for (const KeyframeId id : ids) map.UpdateConnections(id);
  stack->EditHandler(agent, segment, [&](AgentHandler* h) {
    h->last_keyframe = ids.back();
    h->keyframes = keyframes;
  });
  return smap;
}

RedundancyOptions Options() {
  RedundancyOptions o;
  o.min_map_keyframes = 6;
  return o;
}

TEST(RedundancyStage, ThinsLargeMapsButNeverTheirOldestOrAHandlersNewestKeyframe) {
  MapStack stack{MapOptions{}};
  const auto large = BuildMap(&stack, 1, 10, 6);
  const auto small = BuildMap(&stack, 2, 5, 5);  // every keyframe redundant, but below 6 keyframes
  RedundancyStage stage(Options(), &stack);
  std::vector<KeyframeId> reported, removed;
  for (int i = 0; i < 30; ++i) {
    const auto r = stage.Step([&](KeyframeId id) { reported.push_back(id); });
    removed.insert(removed.end(), r.begin(), r.end());
  }
  ASSERT_FALSE(removed.empty()) << "each point seen by 5 others: the large map's inner keyframes are redundant";
  EXPECT_EQ(reported, removed);
  EXPECT_EQ(small->map().num_keyframes(), 5u) << "a map below min_map_keyframes is left alone";
  EXPECT_EQ(large->map().num_keyframes() + removed.size(), 10u);
  for (const KeyframeId id : removed) {
    EXPECT_EQ(id.agent(), 1);
    EXPECT_NE(id, KeyframeId::Make(1, 1)) << "the oldest keyframe fixes the gauge";
    EXPECT_NE(id, KeyframeId::Make(1, 10)) << "the handler's newest keyframe is what the agent's next data links to";
    EXPECT_EQ(large->map().keyframe(id), nullptr);
    EXPECT_TRUE(large->Anchor(id).has_value()) << "a removed keyframe stays in its agent's trajectory as an anchor";
  }
  EXPECT_NE(large->map().keyframe(KeyframeId::Make(1, 1)), nullptr);
  EXPECT_NE(large->map().keyframe(KeyframeId::Make(1, 10)), nullptr);
}

TEST(RedundancyStage, KeepsKeyframesWhosePointsTooFewOthersSee) {
  MapStack stack{MapOptions{}};
  const auto map = BuildMap(&stack, 1, 10, 3);  // each point seen by 2 others: none redundant
  RedundancyStage stage(Options(), &stack);
  int reported = 0;
  for (int i = 0; i < 30; ++i) EXPECT_TRUE(stage.Step([&](KeyframeId) { ++reported; }).empty());
  EXPECT_EQ(reported, 0);
  EXPECT_EQ(map->map().num_keyframes(), 10u);
}

}  // namespace
}  // namespace ccm
