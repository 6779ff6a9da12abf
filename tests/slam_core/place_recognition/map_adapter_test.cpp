// map_adapter: a keyframe of a ccm_map Map becomes the same VerificationView the simulator
// snapshot gives; covisibility is read from the map.
#include <gtest/gtest.h>

#include "slam_core/place_recognition/map_adapter.h"
#include "tests/slam_core/place_recognition/sim_keyframes.h"

namespace ccm::test {
namespace {

// Keyframe snapshots of hall3's first agent (empty if the scene does not load).
std::vector<SimKeyframe> Hall3Keyframes(const SimKeyframeOptions& o) {
  std::string error;
  const auto scenario = sim::LoadScenario("hall3", &error);
  const auto s = scenario ? sim::Simulation::Create(*scenario, &error) : nullptr;
  EXPECT_TRUE(s) << error;
  return s ? MakeSimKeyframes(*s, 0, DefaultVocabulary(), o) : std::vector<SimKeyframe>{};
}

// Puts a simulator snapshot into `map` as a keyframe with one new map point per 3D point.
std::shared_ptr<KeyFrame> AddSnapshot(const SimKeyframe& snap, KeyframeId id, Map* map, IdGenerator<MapPointId>* ids) {
  auto kf = std::make_shared<KeyFrame>(id, 0, snap.view.camera, std::make_shared<const FrameFeatures>(snap.view.features),
                                       std::make_shared<const ScalePyramid>(snap.view.pyramid), snap.world_from_cam);
  if (!map->AddKeyframe(kf)) return nullptr;
  for (int i = 0; i < static_cast<int>(snap.view.features.size()); ++i) {
    if (!snap.view.HasPoint(i)) continue;
    const Eigen::Vector3d p_w = snap.world_from_cam * snap.view.points_cam[i];
    auto mp = std::make_shared<MapPoint>(ids->Next(), p_w, id, snap.view.features.descriptors[i]);
    if (!map->AddMapPoint(mp) || !map->AddObservation(id, i, mp->id())) return nullptr;
  }
  return kf;
}

TEST(MapAdapterTest, KeyframeOfAMapVerifiesAgainstItsSnapshot) {
  SimKeyframeOptions o;
  o.stride = 400;
  const std::vector<SimKeyframe> kfs = Hall3Keyframes(o);
  ASSERT_GE(kfs.size(), 2u);
  const SimKeyframe& snap = kfs[0];

  Map map(MapId::Make(1, 1));
  const KeyframeId kf_id = KeyframeId::Make(1, 1);
  IdGenerator<MapPointId> ids(1);
  const auto kf = AddSnapshot(snap, kf_id, &map, &ids);
  ASSERT_TRUE(kf);
  const size_t num_points = map.num_map_points();
  ASSERT_GT(num_points, 100u);

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

TEST(MapAdapterTest, WindowViewAddsTheNeighboursPointsWhereTheKeyframeSeesThem) {
  SimKeyframeOptions o;
  o.stride = 12;
  o.max_keyframes = 3;
  const std::vector<SimKeyframe> kfs = Hall3Keyframes(o);
  ASSERT_EQ(kfs.size(), 3u);
  Map map(MapId::Make(1, 1));
  IdGenerator<MapPointId> ids(1);
  const auto a = AddSnapshot(kfs[0], KeyframeId::Make(1, 1), &map, &ids);
  const auto b = AddSnapshot(kfs[1], KeyframeId::Make(1, 2), &map, &ids);
  ASSERT_TRUE(a && b);
  const int levels_up = DefaultVocabulary().levels() - 2;

  size_t real = 0;
  const VerificationView alone = MakeVerificationView(*a, map, DefaultVocabulary(), levels_up);
  const KeypointNodesFn nodes = VocabularyNodes(DefaultVocabulary(), levels_up);
  size_t own = 0;
  const VerificationView alone_too = MakeWindowView(*a, {}, map, nodes, &own);
  ASSERT_EQ(own, alone.features.size());
  ASSERT_EQ(alone_too.feature_vector.nodes, alone.feature_vector.nodes) << "the same direct index, from the nodes";
  const VerificationView window = MakeWindowView(*a, {a, b}, map, nodes, &real);
  EXPECT_TRUE(window.Validate().empty()) << window.Validate();
  ASSERT_EQ(real, alone.features.size());
  ASSERT_GT(window.features.size(), real + 50) << "the neighbour's points seen from a add features";
  for (size_t i = 0; i < real; ++i) {
    ASSERT_EQ(window.HasPoint(static_cast<int>(i)), alone.HasPoint(static_cast<int>(i)));
  }
  for (size_t i = real; i < window.features.size(); ++i) {
    // Extra features sit where a's camera sees their point, in a's camera frame.
    ASSERT_TRUE(window.HasPoint(static_cast<int>(i)));
    Eigen::Vector2d uv;
    ASSERT_TRUE(window.camera->Project(window.points_cam[i], &uv));
    EXPECT_NEAR(uv.x(), window.features.keypoints[i].u, 1e-3);
    EXPECT_NEAR(uv.y(), window.features.keypoints[i].v, 1e-3);
    EXPECT_TRUE(window.camera->InImage(uv));
  }

  // The third keyframe, further along the flight, verifies against the window with at least
  // as many BoW matches as against a alone, and the Sim(3) is the true one.
  const VerificationResult with_window = VerifyPlace(window, kfs[2].view);
  const VerificationResult with_a = VerifyPlace(alone, kfs[2].view);
  EXPECT_GE(with_window.bow_matches, with_a.bow_matches);
  ASSERT_TRUE(with_window.accepted) << with_window.reason;
  double trans_m = 0, rot_deg = 0;
  Sim3Error(with_window.query_from_candidate, TrueQueryFromCandidate(kfs[0], kfs[2]), kfs[2].map_scale, &trans_m,
            &rot_deg);
  EXPECT_LT(trans_m, 0.05);
  EXPECT_LT(rot_deg, 1.0);
}

}  // namespace
}  // namespace ccm::test
