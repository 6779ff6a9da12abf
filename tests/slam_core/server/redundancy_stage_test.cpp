// RedundancyStage on hand-built maps: which map it thins (large enough ones, in turn), what it
// never removes (a map's oldest keyframe, a handler's newest), that removed keyframes stay
// as anchors and are reported, and that keyframes whose points too few others see stay; and
// the revisit rule: a second pass over the same place leaves as anchors of the first.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <set>
#include <vector>

#include "slam_core/server/redundancy.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

// Point p (< 30) of a group whose first point is at x0: spread over 2 m across and 0.4 m in
// depth, so a keyframe's pose is determined by its points (anchoring refines it on them).
Eigen::Vector3d GroupPoint(double x0, int p, double depth = 4.5) {
  return {x0 + 0.01 * p, -1.0 + 2.0 * (p % 10) / 9.0, depth + 0.2 * (p / 10)};
}

// Keypoint `idx` at the exact projection of `point` from `world_from_cam` (where the
// keyframe saw it); left where it was if the point is off the image.
void PlaceKeypoint(const CameraModel& camera, FrameFeatures* f, int idx, const SE3& world_from_cam,
                   const Eigen::Vector3d& point) {
  Eigen::Vector2d uv;
  if (!camera.Project(world_from_cam.inverse() * point, &uv)) return;
  f->keypoints[idx].u = static_cast<float>(uv.x());
  f->keypoints[idx].v = static_cast<float>(uv.y());
}

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
  std::vector<std::shared_ptr<FrameFeatures>> features;
  for (int k = 0; k < keyframes; ++k) {
    auto f = std::make_shared<FrameFeatures>();
    features.push_back(f);
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
      const Eigen::Vector3d at = GroupPoint(0.2 * first, p);
      map.AddMapPoint(std::make_shared<MapPoint>(mp, at, ids[first], OrbDescriptor{}));
      for (int k = first; k < first + seen_by; ++k) {
        PlaceKeypoint(*camera, features[k].get(), next_keypoint[k], map.keyframe(ids[k])->world_from_cam(), at);
        map.AddObservation(ids[k], next_keypoint[k]++, mp);
      }
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
  o.revisit_distance_ratio = 0.0;  // CCM-SLAM's rule alone unless a test turns it on
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

// Two passes of `agent` along x over the same points (z = 5 m), the second 40 s later and
// `lateral` metres to the side. Point group k is seen by first-pass keyframes k and k + 1
// and by second-pass keyframe k: two other observers for every point, so CCM-SLAM's rule
// (three others) finds nothing redundant and only the revisit rule can. With `own_points`,
// second-pass keyframes k and k + 1 also share that many points nobody else sees (what an
// agent maps anew on a pass): an inner second-pass keyframe then covers 30 / (30 + 2 x own).
// `second_pass_error`: the second pass's keyframes sit at truth x error (their keypoints are
// where the truth sees the points), as a loop's Sim(3) leaves them until the next BA.
struct TwoPasses {
  std::shared_ptr<ServerMap> map;
  std::vector<KeyframeId> first, second;
  std::vector<std::shared_ptr<FrameFeatures>> features;  ///< first pass, then second
};
TwoPasses BuildTwoPasses(MapStack* stack, AgentId agent, double lateral, int own_points = 0,
                         const SE3& second_pass_error = SE3()) {
  constexpr int kFirst = 8, kPoints = 30;
  const MapId segment = MapId::Make(agent, 1);
  TwoPasses t;
  t.map = stack->MapFor(agent, segment);
  Map& map = t.map->map();
  const auto camera = testing::TestCamera();
  const auto pyramid = std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2));
  std::vector<int> used;
  std::vector<SE3> truth;
  const auto add = [&](int counter, int64_t stamp_ns, Eigen::Vector3d at, const SE3& error) {
    auto f = std::make_shared<FrameFeatures>();
    t.features.push_back(f);
    for (int i = 0; i < 2 * kPoints; ++i) {
      Keypoint kp;
      kp.u = static_cast<float>(10 + (i * 37) % 700);
      kp.v = static_cast<float>(10 + (i * 53) % 460);
      f->keypoints.push_back(kp);
      f->descriptors.push_back(OrbDescriptor{});
    }
    const KeyframeId id = KeyframeId::Make(agent, counter);
    const SE3 pose(Eigen::Quaterniond::Identity(), at);
    map.AddKeyframe(std::make_shared<KeyFrame>(id, stamp_ns, camera, f, pyramid, pose * error));
    truth.push_back(pose);
    used.push_back(0);
    return id;
  };
  // Keypoint of keyframe `idx` (first pass, then second) for `mp` at `at`, seen from the truth.
  const auto observe = [&](size_t idx, MapPointId mp, const Eigen::Vector3d& at) {
    const KeyframeId kf = idx < static_cast<size_t>(kFirst) ? t.first[idx] : t.second[idx - kFirst];
    PlaceKeypoint(*camera, t.features[idx].get(), used[idx], truth[idx], at);
    map.AddObservation(kf, used[idx]++, mp);
  };
  for (int k = 0; k < kFirst; ++k) t.first.push_back(add(k + 1, int64_t{500000000} * (k + 1), {0.4 * k, 0, 0}, SE3()));
  for (int k = 0; k + 1 < kFirst; ++k) {
    t.second.push_back(add(kFirst + k + 1, int64_t{40000000000} + int64_t{500000000} * (k + 1), {0.4 * k, lateral, 0},
                           second_pass_error));
  }
  uint64_t point = 0;
  for (int k = 0; k + 1 < kFirst; ++k) {
    for (int p = 0; p < kPoints; ++p) {
      const MapPointId mp = MapPointId::Make(agent, ++point);
      const Eigen::Vector3d at = GroupPoint(0.4 * k, p);
      map.AddMapPoint(std::make_shared<MapPoint>(mp, at, t.first[k], OrbDescriptor{}));
      for (const int idx : {k, k + 1, kFirst + k}) observe(idx, mp, at);
    }
  }
  for (size_t k = 0; k + 1 < t.second.size(); ++k) {
    for (int p = 0; p < own_points; ++p) {
      const MapPointId mp = MapPointId::Make(agent, ++point);
      const Eigen::Vector3d at = GroupPoint(0.4 * k, p, 5.2);
      map.AddMapPoint(std::make_shared<MapPoint>(mp, at, t.second[k], OrbDescriptor{}));
      for (const size_t idx : {k, k + 1}) observe(kFirst + idx, mp, at);
    }
  }
  for (const auto& kf : map.keyframes()) map.UpdateConnections(kf->id());
  stack->EditHandler(agent, segment, [&](AgentHandler* h) {
    h->last_keyframe = t.second.back();
    h->keyframes = static_cast<int>(t.first.size() + t.second.size());
  });
  return t;
}

std::vector<KeyframeId> StepMany(RedundancyStage* stage, int steps) {
  std::vector<KeyframeId> removed;
  for (int i = 0; i < steps; ++i) {
    const auto r = stage->Step([](KeyframeId) {});
    removed.insert(removed.end(), r.begin(), r.end());
  }
  return removed;
}

TEST(RedundancyStage, ASecondPassOverTheSamePlaceLeavesAsAnchorsOfTheFirst) {
  RedundancyOptions options = Options();
  options.revisit_distance_ratio = 0.2;  // 1 m at 5 m of scene depth
  options.revisit_settle_s = 0.0;        // the whole second pass is behind the agent
  MapStack stack{MapOptions{}};
  const TwoPasses t = BuildTwoPasses(&stack, 1, 0.1);
  RedundancyStage stage(options, &stack);
  const auto removed = StepMany(&stage, 60);
  const std::set<KeyframeId> gone(removed.begin(), removed.end());
  for (const KeyframeId id : t.first) EXPECT_FALSE(gone.count(id)) << "the first pass stays: it is the older one";
  EXPECT_FALSE(gone.count(t.second.back())) << "the handler's newest keyframe stays";
  EXPECT_EQ(gone.size(), t.second.size() - 1) << "every other second-pass keyframe duplicates a first-pass one";
  for (const KeyframeId id : removed) {
    const auto anchor = t.map->Anchor(id);
    ASSERT_TRUE(anchor.has_value());
    const auto base = std::find(t.first.begin(), t.first.end(), anchor->base);
    ASSERT_NE(base, t.first.end()) << "anchored to the first-pass keyframe it duplicates";
    const size_t k = std::find(t.second.begin(), t.second.end(), id) - t.second.begin();
    const size_t b = static_cast<size_t>(base - t.first.begin());
    EXPECT_TRUE(b == k || b == k + 1)
        << "the duplicated keyframe is one of the two that see the same points";
    EXPECT_NEAR(t.map->PoseOf(id)->translation().y(), 0.1, 1e-4) << "its pose survives through the anchor";
  }
}

TEST(RedundancyStage, ARevisitTooFarToTheSideJustFlownOrWithTheRuleOffStays) {
  RedundancyOptions options = Options();
  options.revisit_distance_ratio = 0.2;
  options.revisit_settle_s = 0.0;
  MapStack far_stack{MapOptions{}};
  BuildTwoPasses(&far_stack, 1, 1.5);  // 1.5 m to the side: beyond 0.2 x 5 m
  RedundancyStage far(options, &far_stack);
  EXPECT_TRUE(StepMany(&far, 60).empty());

  MapStack recent_stack{MapOptions{}};
  const TwoPasses recent = BuildTwoPasses(&recent_stack, 1, 0.1);
  options.revisit_settle_s = 2.0;  // the second pass's last 2 s are what the agent flies now
  RedundancyStage settle(options, &recent_stack);
  const auto removed = StepMany(&settle, 60);
  const int64_t newest = recent.map->map().keyframe(recent.second.back())->stamp_ns();
  EXPECT_EQ(removed.size(), 3u) << "of the six before the newest, the three at least 2 s behind it";
  for (const KeyframeId id : removed) {
    EXPECT_LE(recent.map->Anchor(id)->stamp_ns + int64_t{2000000000}, newest);
  }

  MapStack off_stack{MapOptions{}};
  BuildTwoPasses(&off_stack, 1, 0.1);
  options.revisit_distance_ratio = 0.0;  // CCM-SLAM's rule only
  options.revisit_settle_s = 0.0;
  RedundancyStage off(options, &off_stack);
  EXPECT_TRUE(StepMany(&off, 60).empty());
}

TEST(RedundancyStage, TheEndOfRunSweepTakesTheRevisitsTheSettleHeldBackAndNothingElse) {
  RedundancyOptions options = Options();
  options.revisit_distance_ratio = 0.2;
  options.revisit_settle_s = 2.0;
  MapStack stack{MapOptions{}};
  const TwoPasses t = BuildTwoPasses(&stack, 1, 0.1);
  RedundancyStage stage(options, &stack);
  const auto during = StepMany(&stage, 60);
  ASSERT_EQ(during.size(), 3u) << "the settle holds the last 2 s of the second pass back";
  int erased = 0;
  const auto swept = stage.SweepRevisits(t.map->id(), [&](KeyframeId) { ++erased; });
  EXPECT_EQ(swept.size(), 3u) << "the three the settle held, in one call";
  EXPECT_EQ(erased, 3) << "each reported while the map is locked";
  std::set<KeyframeId> gone(during.begin(), during.end());
  gone.insert(swept.begin(), swept.end());
  EXPECT_EQ(gone.size(), t.second.size() - 1) << "the whole second pass but the handler's newest keyframe";
  EXPECT_FALSE(gone.count(t.second.back()));
  for (const KeyframeId id : t.first) EXPECT_TRUE(t.map->map().keyframe(id)) << "the first pass stays";
  for (const KeyframeId id : swept) {
    const auto anchor = t.map->Anchor(id);
    ASSERT_TRUE(anchor.has_value());
    EXPECT_NE(std::find(t.first.begin(), t.first.end(), anchor->base), t.first.end());
  }
  EXPECT_TRUE(stage.SweepRevisits(t.map->id(), [](KeyframeId) {}).empty()) << "a second sweep finds nothing left";

  MapStack far_stack{MapOptions{}};
  const TwoPasses far = BuildTwoPasses(&far_stack, 1, 1.5);
  RedundancyStage far_stage(options, &far_stack);
  EXPECT_TRUE(far_stage.SweepRevisits(far.map->id(), [](KeyframeId) {}).empty()) << "1.5 m to the side is no revisit";

  // What the agent mapped anew on its second pass: 6 points shared with each neighbour
  // (30 / 42 = 71 % covered) keep the live rule (80 %) from taking the inner keyframes but
  // not the sweep (70 %); 8 (65 %) keep both from it.
  for (const int own : {6, 8}) {
    MapStack own_stack{MapOptions{}};
    const TwoPasses o = BuildTwoPasses(&own_stack, 1, 0.1, own);
    RedundancyOptions live = options;
    live.revisit_settle_s = 0.0;
    RedundancyStage own_stage(live, &own_stack);
    const auto live_removed = StepMany(&own_stage, 60);
    const auto own_swept = own_stage.SweepRevisits(o.map->id(), [](KeyframeId) {});
    for (size_t k = 1; k + 1 < o.second.size(); ++k) {
      const KeyframeId id = o.second[k];
      EXPECT_EQ(std::count(live_removed.begin(), live_removed.end(), id), 0) << "own " << own << ", inner " << k;
      EXPECT_EQ(std::count(own_swept.begin(), own_swept.end(), id), own == 6 ? 1 : 0) << "own " << own;
    }
  }

  RedundancyOptions disabled = options;
  disabled.enabled = false;  // a run that keeps every keyframe keeps them at its end too
  MapStack kept_stack{MapOptions{}};
  const TwoPasses kept = BuildTwoPasses(&kept_stack, 1, 0.1);
  RedundancyStage kept_stage(disabled, &kept_stack);
  EXPECT_TRUE(kept_stage.SweepRevisits(kept.map->id(), [](KeyframeId) {}).empty());
}

TEST(RedundancyStage, AnAnchorKeepsThePoseItsPointsGiveNotTheOneALoopLeftIt) {
  RedundancyOptions options = Options();
  options.revisit_distance_ratio = 0.2;
  options.revisit_settle_s = 0.0;
  // 4 cm and 1 deg off, as a loop's correction may leave a second pass until the next BA.
  const SE3 error(Eigen::Quaterniond(Eigen::AngleAxisd(0.0175, Eigen::Vector3d::UnitZ())), {0.03, -0.02, 0.02});
  MapStack stack{MapOptions{}};
  const TwoPasses t = BuildTwoPasses(&stack, 1, 0.1, 0, error);
  // One keyframe whose links all disagree with any pose (its keypoints shuffled): it stays.
  auto& keypoints = t.features[t.first.size() + 3]->keypoints;
  std::reverse(keypoints.begin(), keypoints.end());
  RedundancyRemover remover(options);
  std::vector<KeyframeId> protect{t.second.back()};
  const RedundancyStep step = remover.SweepRevisits(t.map.get(), protect);
  EXPECT_EQ(step.removed.size(), t.second.size() - 2) << "all inner second-pass keyframes but the shuffled one";
  EXPECT_EQ(step.refused, 1);
  EXPECT_NE(t.map->map().keyframe(t.second[3]), nullptr) << "left for the BA";
  for (const KeyframeId id : step.removed) {
    const size_t k = std::find(t.second.begin(), t.second.end(), id) - t.second.begin();
    const Eigen::Vector3d truth(0.4 * static_cast<double>(k), 0.1, 0.0);
    EXPECT_LT((t.map->PoseOf(id)->translation() - truth).norm(), 0.002) << "keyframe " << k << " was 4 cm off";
  }
}

}  // namespace
}  // namespace ccm
