// map_adapter: a keyframe of a ccm_map Map becomes the same VerificationView the simulator
// snapshot gives; covisibility is read from the map.
#include <gtest/gtest.h>

#include "slam_core/place_recognition/map_adapter.h"
#include "tests/slam_core/place_recognition/sim_keyframes.h"

namespace ccm::test {
namespace {

TEST(MapAdapterTest, KeyframeOfAMapVerifiesAgainstItsSnapshot) {
  std::string error;
  auto scenario = sim::LoadScenario("hall3", &error);
  ASSERT_TRUE(scenario) << error;
  auto s = sim::Simulation::Create(*scenario, &error);
  ASSERT_TRUE(s) << error;
  SimKeyframeOptions o;
  o.stride = 400;
  const std::vector<SimKeyframe> kfs = MakeSimKeyframes(*s, 0, DefaultVocabulary(), o);
  ASSERT_GE(kfs.size(), 2u);
  const SimKeyframe& snap = kfs[0];

  Map map(MapId::Make(1, 1));
  const KeyframeId kf_id = KeyframeId::Make(1, 1);
  auto kf = std::make_shared<KeyFrame>(kf_id, 0, snap.view.camera,
                                       std::make_shared<const FrameFeatures>(snap.view.features),
                                       std::make_shared<const ScalePyramid>(snap.view.pyramid),
                                       snap.world_from_cam);
  ASSERT_TRUE(map.AddKeyframe(kf));
  IdGenerator<MapPointId> ids(1);
  int num_points = 0;
  for (int i = 0; i < static_cast<int>(snap.view.features.size()); ++i) {
    if (!snap.view.HasPoint(i)) continue;
    const Eigen::Vector3d p_w = snap.world_from_cam * snap.view.points_cam[i];
    auto mp = std::make_shared<MapPoint>(ids.Next(), p_w, kf_id, snap.view.features.descriptors[i]);
    ASSERT_TRUE(map.AddMapPoint(mp));
    ASSERT_TRUE(map.AddObservation(kf_id, i, mp->id()));
    ++num_points;
  }
  ASSERT_GT(num_points, 100);

  BowVector bow;
  const int levels_up = DefaultVocabulary().levels() - 2;  // as MakeSimKeyframes: depth 2
  const VerificationView view = MakeVerificationView(*kf, map, DefaultVocabulary(), levels_up, &bow);
  EXPECT_EQ(bow.entries, snap.bow.entries);
  ASSERT_EQ(view.points_cam.size(), snap.view.points_cam.size());
  for (std::size_t i = 0; i < view.points_cam.size(); ++i) {
    ASSERT_EQ(view.HasPoint(static_cast<int>(i)), snap.view.HasPoint(static_cast<int>(i)));
    if (view.HasPoint(static_cast<int>(i))) {
      EXPECT_LT((view.points_cam[i] - snap.view.points_cam[i]).norm(), 1e-6);
    }
  }
  const VerificationResult r = VerifyPlace(view, snap.view);
  EXPECT_TRUE(r.accepted) << r.reason;

  // No covisible neighbours yet; unknown keyframes give nothing.
  const CovisibilityFn covis = MapCovisibility(map);
  EXPECT_TRUE(covis(kf_id, 10).empty());
  EXPECT_TRUE(covis(KeyframeId::Make(9, 9), 10).empty());
}

}  // namespace
}  // namespace ccm::test
