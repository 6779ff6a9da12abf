// Map fusion welds the whole overlap, not just the verified pair's neighbourhood: two agents
// flew the same 20 m wall (exact geometry, the second map in another Sim(3) frame); a fusion
// detected at the start of the wall must leave the keyframes at its far end sharing their
// points too (with the weld off they keep separate copies: nothing but the pair held the
// parts together), and the weld must merge only true duplicates (the same scene point).
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "slam_core/server/map_fuser.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace overlap_weld_test {  // named: server_test is a unity build

constexpr int kViews = 40;      // 0.5 m apart along x, looking along +z at a wall ~5 m away
constexpr int kPoints = 2500;
constexpr int kFarView = 25;    // from here on nothing is covisible with the detected pair

struct Wall {
  std::vector<Eigen::Vector3d> points;
  std::vector<OrbDescriptor> descriptors;
};

Wall MakeWall() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(-4.0, 24.0), y(-2.0, 2.0), z(4.5, 5.5);
  std::uniform_int_distribution<int> byte(0, 255);
  Wall w;
  for (int i = 0; i < kPoints; ++i) {
    w.points.emplace_back(x(rng), y(rng), z(rng));
    OrbDescriptor d;
    for (auto& b : d) b = static_cast<uint8_t>(byte(rng));
    w.descriptors.push_back(d);
  }
  return w;
}

SE3 TruePose(int k) { return SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.5 * k, 0.0, 0.0)); }

// `agent`'s map of the wall in the frame world_from_true; each keyframe observes the points in
// its image. point_of[k][j]: the wall point keypoint j of view k shows.
struct AgentMap {
  std::shared_ptr<ServerMap> map;
  std::vector<std::vector<int>> point_of;
};

AgentMap BuildMap(MapStack* stack, AgentId agent, const Wall& wall, const Sim3& world_from_true) {
  AgentMap out;
  const MapId segment = MapId::Make(agent, 1);
  out.map = stack->MapFor(agent, segment);
  Map& map = out.map->map();
  const auto camera = testing::TestCamera();
  const auto pyramid = std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2));
  std::vector<std::vector<std::pair<KeyframeId, int>>> seen_by(kPoints);
  for (int k = 0; k < kViews; ++k) {
    auto f = std::make_shared<FrameFeatures>();
    std::vector<int> shows;
    for (int i = 0; i < kPoints; ++i) {
      Eigen::Vector2d uv;
      if (!camera->Project(TruePose(k).inverse() * wall.points[i], &uv)) continue;
      if (uv.x() < 0 || uv.y() < 0 || uv.x() >= 752 || uv.y() >= 480) continue;
      Keypoint kp;
      kp.u = static_cast<float>(uv.x());
      kp.v = static_cast<float>(uv.y());
      f->keypoints.push_back(kp);
      f->descriptors.push_back(wall.descriptors[i]);
      seen_by[i].emplace_back(KeyframeId::Make(agent, k + 1), static_cast<int>(shows.size()));
      shows.push_back(i);
    }
    out.point_of.push_back(shows);
    map.AddKeyframe(std::make_shared<KeyFrame>(KeyframeId::Make(agent, k + 1), int64_t{100000000} * (k + 1), camera, f,
                                               pyramid, world_from_true.TransformPose(TruePose(k))));
  }
  for (int i = 0; i < kPoints; ++i) {
    if (seen_by[i].size() < 2) continue;
    const MapPointId mp = MapPointId::Make(agent, i + 1);
    map.AddMapPoint(
        std::make_shared<MapPoint>(mp, world_from_true * wall.points[i], seen_by[i][0].first, wall.descriptors[i]));
    for (const auto& [kf, idx] : seen_by[i]) map.AddObservation(kf, idx, mp);
    map.UpdateMapPointAppearance(mp);
  }
  for (int k = 0; k < kViews; ++k) map.UpdateConnections(KeyframeId::Make(agent, k + 1));
  return out;
}

struct Shared {
  int same = 0;   // keypoints of the far views whose two agents' copies are one map point
  int wrong = 0;  // keypoints whose point was merged with another wall point's
  int total = 0;
};

Shared FuseAtTheStart(double weld_depth_ratio) {
  const Wall wall = MakeWall();
  MapStack stack{MapOptions{}};
  const AgentMap a = BuildMap(&stack, 1, wall, Sim3());
  const Sim3 world2_from_true(0.7, Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY())),
                              Eigen::Vector3d(1.0, 0.5, -2.0));
  const AgentMap b = BuildMap(&stack, 2, wall, world2_from_true);
  constexpr int kDetected = 2;
  PlaceDetection d;
  d.kind = PlaceDetection::Kind::kFusion;
  d.query = KeyframeId::Make(2, kDetected + 1);
  d.candidate = KeyframeId::Make(1, kDetected + 1);
  d.query_map = b.map->id();
  d.candidate_map = a.map->id();
  d.query_from_candidate = Sim3(0.7, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  for (size_t j = 0; j < a.point_of[kDetected].size(); ++j) d.matches.push_back({static_cast<int>(j), static_cast<int>(j), 0});
  d.inliers = static_cast<int>(d.matches.size());
  const FusionReport r = FuseMaps(&stack, d, weld_depth_ratio, nullptr);
  EXPECT_TRUE(r.fused) << r.reason;
  EXPECT_EQ(stack.num_maps(), 1u);
  const Map& map = stack.Maps().front()->map();
  Shared s;
  for (int k = kFarView; k < kViews; ++k) {
    const auto ka = map.keyframe(KeyframeId::Make(1, k + 1)), kb = map.keyframe(KeyframeId::Make(2, k + 1));
    if (!ka || !kb) {
      ADD_FAILURE() << "view " << k << " left the map";
      continue;
    }
    // Index the first agent's copy by wall point, then look the second agent's up.
    std::map<int, MapPointId> of_a;
    for (size_t j = 0; j < a.point_of[k].size(); ++j) of_a[a.point_of[k][j]] = ka->MapPointAt(j);
    for (size_t j = 0; j < b.point_of[k].size(); ++j) {
      const MapPointId pb = kb->MapPointAt(j);
      if (!pb.valid()) continue;
      ++s.total;
      const auto it = of_a.find(b.point_of[k][j]);
      if (it != of_a.end() && it->second == pb) ++s.same;
      for (size_t i = 0; i < a.point_of[k].size(); ++i) {
        if (ka->MapPointAt(i) == pb && a.point_of[k][i] != b.point_of[k][j]) ++s.wrong;
      }
    }
  }
  return s;
}

TEST(OverlapWeld, AFusionJoinsTheWholeOverlapNotJustTheDetectedViews) {
  const Shared welded = FuseAtTheStart(0.5);
  ASSERT_GT(welded.total, 1000);
  EXPECT_GT(welded.same, 0.9 * welded.total) << welded.same << " of " << welded.total;
  EXPECT_EQ(welded.wrong, 0);
  // Without the weld the far end keeps two copies of every point.
  const Shared local = FuseAtTheStart(0.0);
  EXPECT_LT(local.same, 0.05 * local.total) << local.same << " of " << local.total;
  EXPECT_EQ(local.wrong, 0);
}

}  // namespace overlap_weld_test
}  // namespace ccm
