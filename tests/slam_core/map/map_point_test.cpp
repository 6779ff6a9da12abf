#include <gtest/gtest.h>

#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

TEST(MapPoint, AppearanceUsesMedianDescriptorMeanNormalAndPyramidDepthRange) {
  testing::MapBuilder b;
  const KeyframeId k1 = b.AddKeyframe(0.0), k2 = b.AddKeyframe(1.0), k3 = b.AddKeyframe(2.0);
  const MapPointId id = b.AddPointSeenBy({k1, k2, k3}, Eigen::Vector3d(1.0, 0.0, 4.0));
  b.map().UpdateMapPointAppearance(id);
  const auto mp = b.map().map_point(id);
  // Normal: mean of unit rays from the three camera centres to the point.
  Eigen::Vector3d expected = Eigen::Vector3d::Zero();
  for (double x : {0.0, 1.0, 2.0}) expected += (Eigen::Vector3d(1, 0, 4) - Eigen::Vector3d(x, 0, 0)).normalized();
  EXPECT_LT((mp->normal() - expected.normalized()).norm(), 1e-12);
  // Depth range from the reference keyframe k1 and the level of its keypoint.
  const auto ref = b.map().keyframe(k1);
  const int level = ref->features().keypoints[*mp->KeypointIn(k1)].level;
  const double dist = std::sqrt(17.0);
  EXPECT_NEAR(mp->max_distance_m(), dist * std::pow(1.2, level), 1e-9);
  EXPECT_NEAR(mp->min_distance_m(), mp->max_distance_m() / std::pow(1.2, 7), 1e-9);
  // The chosen descriptor is one of the observations' descriptors.
  bool found = false;
  for (const auto& [kf, idx] : mp->observations()) found |= b.map().keyframe(kf)->features().descriptors[idx] == mp->descriptor();
  EXPECT_TRUE(found);
}

TEST(MapPoint, MedianDescriptorPicksTheCentralOne) {
  // The representative descriptor must minimise the median distance to all observed
  // descriptors (ORB-SLAM's rule); checked against a brute-force evaluation.
  testing::MapBuilder b(1);
  const KeyframeId ka = b.AddKeyframe(0), kb = b.AddKeyframe(1), kc = b.AddKeyframe(2);
  const MapPointId id = b.AddPointSeenBy({ka, kb, kc});
  const auto mp = b.map().map_point(id);
  b.map().UpdateMapPointAppearance(id);
  std::vector<OrbDescriptor> d;
  for (const auto& [kf, idx] : mp->observations()) d.push_back(b.map().keyframe(kf)->features().descriptors[idx]);
  auto median_of = [&](const OrbDescriptor& x) {
    std::vector<int> v;
    for (const auto& y : d) v.push_back(HammingDistance(x, y));
    std::sort(v.begin(), v.end());
    return v[1];
  };
  int best = 1 << 20;
  for (const auto& x : d) best = std::min(best, median_of(x));
  EXPECT_EQ(median_of(mp->descriptor()), best);
}

// The descriptor is kept across updates while the observations stay the same (the point
// only moved, as after a BA) and follows them as soon as they change.
TEST(MapPoint, DescriptorFollowsTheObservationsNotThePosition) {
  testing::MapBuilder b(3);
  const KeyframeId k1 = b.AddKeyframe(0), k2 = b.AddKeyframe(1), k3 = b.AddKeyframe(2), k4 = b.AddKeyframe(3);
  const MapPointId id = b.AddPointSeenBy({k1, k2, k3, k4});
  const auto mp = b.map().map_point(id);
  b.map().UpdateMapPointAppearance(id);
  const OrbDescriptor first = mp->descriptor();
  const Eigen::Vector3d first_normal = mp->normal();
  mp->SetPosition(mp->position() + Eigen::Vector3d(2.0, 0.0, 0.0));
  b.map().UpdateMapPointAppearance(id);
  EXPECT_EQ(mp->descriptor(), first);
  EXPECT_GT((mp->normal() - first_normal).norm(), 0.1) << "the geometry follows the move";
  // Erase the keyframe whose descriptor represents the point: a new one must be chosen.
  KeyframeId chosen;
  for (const auto& [kf, idx] : mp->observations()) {
    if (b.map().keyframe(kf)->features().descriptors[idx] == first) chosen = kf;
  }
  ASSERT_TRUE(chosen.valid());
  b.map().EraseObservation(chosen, id);
  b.map().UpdateMapPointAppearance(id);
  bool from_remaining = false;
  for (const auto& [kf, idx] : mp->observations()) {
    from_remaining |= b.map().keyframe(kf)->features().descriptors[idx] == mp->descriptor();
  }
  EXPECT_TRUE(from_remaining);
  EXPECT_NE(mp->descriptor(), first);
}

TEST(MapPoint, PredictLevelGrowsWhenCloser) {
  MapPoint mp(MapPointId::Make(1, 1), {0, 0, 5}, KeyframeId::Make(1, 1), OrbDescriptor{});
  const ScalePyramid pyr = ScalePyramid::Make(8, 1.2);
  mp.SetAppearance(OrbDescriptor{}, {0, 0, 1}, 10.0 / std::pow(1.2, 7), 10.0);
  EXPECT_EQ(mp.PredictLevel(10.0, pyr), 0);
  EXPECT_EQ(mp.PredictLevel(10.0 / 1.2 / 1.2 * 1.0001, pyr), 2);
  EXPECT_EQ(mp.PredictLevel(0.1, pyr), 7);
}

TEST(MapPoint, ObservationsStaySortedAndUnique) {
  MapPoint mp(MapPointId::Make(1, 1), {0, 0, 5}, KeyframeId::Make(1, 3), OrbDescriptor{});
  EXPECT_TRUE(mp.AddObservation(KeyframeId::Make(1, 3), 7));
  EXPECT_TRUE(mp.AddObservation(KeyframeId::Make(1, 1), 2));
  EXPECT_FALSE(mp.AddObservation(KeyframeId::Make(1, 3), 9));
  const auto obs = mp.observations();
  ASSERT_EQ(obs.size(), 2u);
  EXPECT_EQ(obs[0].first, KeyframeId::Make(1, 1));
  EXPECT_EQ(*mp.KeypointIn(KeyframeId::Make(1, 3)), 7);
  EXPECT_TRUE(mp.EraseObservation(KeyframeId::Make(1, 1)));
  EXPECT_FALSE(mp.KeypointIn(KeyframeId::Make(1, 1)).has_value());
}

}  // namespace
}  // namespace ccm
