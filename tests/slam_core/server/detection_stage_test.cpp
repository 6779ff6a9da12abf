// DetectionStage on hand-built maps with exact geometry: two agents mapped the same scene,
// the second in a world frame that differs by a known Sim(3). A fusion detection between the
// same view in both maps must leave one map in which each pair of keyframes of the same view
// coincides and the scale is the first map's; a loop detection must close and be reported;
// a detection of a keyframe the stack does not hold must change nothing. The loop's pose
// graph is solved with the map unlocked: keyframes and points added meanwhile must follow
// their ancestor's correction.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "slam_core/server/detection_stage.h"
#include "slam_core/server/map_correction.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

constexpr int kKeyframes = 8;
constexpr int kPoints = 300;

struct Scene {
  std::vector<Eigen::Vector3d> points;
  std::vector<OrbDescriptor> descriptors;
};

Scene MakeScene() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-3.0, 3.0), y(-2.0, 2.0), z(4.0, 6.0);
  std::uniform_int_distribution<int> byte(0, 255);
  Scene s;
  for (int i = 0; i < kPoints; ++i) {
    s.points.emplace_back(x(rng), y(rng), z(rng));
    OrbDescriptor d;
    for (auto& b : d) b = static_cast<uint8_t>(byte(rng));
    s.descriptors.push_back(d);
  }
  return s;
}

// True camera pose of view k: 20 cm steps along x, looking along +z.
SE3 TruePose(int k) { return SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.2 * k, 0.0, 0.0)); }

// `agent`'s map of the scene in the world frame world_from_true (a similarity): keypoint i of
// every keyframe is point i (projected exactly; every point is in view of every keyframe).
std::shared_ptr<ServerMap> BuildMap(MapStack* stack, AgentId agent, const Scene& scene, const Sim3& world_from_true) {
  const MapId segment = MapId::Make(agent, 1);
  auto smap = stack->MapFor(agent, segment);
  Map& map = smap->map();
  const auto camera = testing::TestCamera();
  const auto pyramid = std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2));
  std::vector<KeyframeId> ids;
  for (int k = 0; k < kKeyframes; ++k) {
    const SE3 true_pose = TruePose(k);
    auto f = std::make_shared<FrameFeatures>();
    for (int i = 0; i < kPoints; ++i) {
      Eigen::Vector2d uv;
      EXPECT_TRUE(camera->Project(true_pose.inverse() * scene.points[i], &uv));
      Keypoint kp;
      kp.u = static_cast<float>(uv.x());
      kp.v = static_cast<float>(uv.y());
      f->keypoints.push_back(kp);
      f->descriptors.push_back(scene.descriptors[i]);
    }
    const SE3 pose = world_from_true.TransformPose(true_pose);
    const KeyframeId id = KeyframeId::Make(agent, k + 1);
    map.AddKeyframe(std::make_shared<KeyFrame>(id, int64_t{50000000} * (k + 1), camera, f, pyramid, pose));
    ids.push_back(id);
  }
  for (int i = 0; i < kPoints; ++i) {
    const MapPointId mp = MapPointId::Make(agent, i + 1);
    map.AddMapPoint(std::make_shared<MapPoint>(mp, world_from_true * scene.points[i], ids[0], scene.descriptors[i]));
    for (int k = 0; k < kKeyframes; ++k) map.AddObservation(ids[k], i, mp);
    map.UpdateMapPointAppearance(mp);
  }
  for (const KeyframeId id : ids) map.UpdateConnections(id);
  stack->EditHandler(agent, segment, [&](AgentHandler* h) {
    h->last_keyframe = ids.back();
    h->keyframes = kKeyframes;
  });
  return smap;
}

// Query keyframe k of `query_agent` against keyframe k of `candidate_agent`: the same view, so
// the camera frames differ only by the ratio of the two maps' scales.
PlaceDetection SameView(const MapStack& stack, PlaceDetection::Kind kind, AgentId query_agent, AgentId candidate_agent,
                        int k, double scale) {
  PlaceDetection d;
  d.kind = kind;
  d.query = KeyframeId::Make(query_agent, k + 1);
  d.candidate = KeyframeId::Make(candidate_agent, k + 1);
  d.query_map = stack.MapHolding(d.query)->id();
  d.candidate_map = stack.MapHolding(d.candidate)->id();
  d.query_from_candidate = Sim3(scale, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  for (int i = 0; i < kPoints; ++i) d.matches.push_back({i, i, 0});
  d.inliers = kPoints;
  return d;
}

struct HookLog {
  std::vector<MapId> loops;
  std::vector<std::pair<MapId, MapId>> fusions;  // (absorbed, kept)
  DetectionStage::Hooks Hooks() {
    return {[this](MapId m) { loops.push_back(m); }, [this](MapId a, MapId k) { fusions.emplace_back(a, k); }};
  }
};

TEST(DetectionStage, AFusionJoinsTheSameViewsOfTwoMapsAndAsksForTheirGlobalBa) {
  const Scene scene = MakeScene();
  MapStack stack{MapOptions{}};
  BuildMap(&stack, 1, scene, Sim3());
  // Agent 2's world: rotated 30 deg about the vertical, shifted and at 0.6 of the scale.
  const Sim3 world2_from_true(0.6, Eigen::Quaterniond(Eigen::AngleAxisd(0.52, Eigen::Vector3d::UnitY())),
                              Eigen::Vector3d(2.0, -1.0, 0.5));
  BuildMap(&stack, 2, scene, world2_from_true);
  ServerOptions options;
  HookLog hooks;
  const DetectionStage stage(&stack, options, hooks.Hooks());

  const DetectionOutcome out = stage.Handle(SameView(stack, PlaceDetection::Kind::kFusion, 2, 1, 4, 0.6), 12.5);
  ASSERT_TRUE(out.event.has_value()) << "the fusion was refused: " << out.refused;
  EXPECT_EQ(out.event->kind, ServerEvent::Kind::kFusion);
  EXPECT_EQ(out.event->time_s, 12.5);
  EXPECT_EQ(out.event->keyframes, 2 * kKeyframes);
  ASSERT_EQ(hooks.fusions.size(), 1u);
  EXPECT_EQ(hooks.fusions[0], std::make_pair(out.event->other_map, out.event->map));
  EXPECT_EQ(out.forget, out.event->other_map);
  EXPECT_EQ(out.optimize, options.optimization.global_ba_after_fusion ? out.event->map : MapId());
  EXPECT_TRUE(hooks.loops.empty());

  ASSERT_EQ(stack.Maps().size(), 1u);
  const auto fused = stack.Maps().front();
  ASSERT_EQ(fused->map().num_keyframes(), static_cast<size_t>(2 * kKeyframes));
  // Both agents' copies of each view coincide, and the map keeps a consistent scale: view
  // spacing in the fused map is one value for both agents.
  const double spacing1 = (fused->map().keyframe(KeyframeId::Make(1, kKeyframes))->camera_center() -
                           fused->map().keyframe(KeyframeId::Make(1, 1))->camera_center()).norm();
  for (int k = 0; k < kKeyframes; ++k) {
    const auto a = fused->map().keyframe(KeyframeId::Make(1, k + 1));
    const auto b = fused->map().keyframe(KeyframeId::Make(2, k + 1));
    ASSERT_TRUE(a && b);
    EXPECT_LT((a->camera_center() - b->camera_center()).norm(), 1e-3 * spacing1) << "view " << k;
    EXPECT_LT(a->world_from_cam().rotation().angularDistance(b->world_from_cam().rotation()), 1e-4)
        << "view " << k;
  }
}

TEST(DetectionStage, AConsistentLoopClosesAndIsReported) {
  const Scene scene = MakeScene();
  MapStack stack{MapOptions{}};
  const auto map = BuildMap(&stack, 1, scene, Sim3());
  ServerOptions options;
  HookLog hooks;
  const DetectionStage stage(&stack, options, hooks.Hooks());
  // The last view against the first: their true relative similarity.
  PlaceDetection d = SameView(stack, PlaceDetection::Kind::kLoop, 1, 1, kKeyframes - 1, 1.0);
  d.candidate = KeyframeId::Make(1, 1);
  const SE3 q_from_c = TruePose(kKeyframes - 1).inverse() * TruePose(0);
  d.query_from_candidate = Sim3(q_from_c);
  const Eigen::Vector3d before = map->map().keyframe(d.query)->camera_center();

  const DetectionOutcome out = stage.Handle(d, 3.0);
  ASSERT_TRUE(out.event.has_value()) << "the loop was refused: " << out.refused;
  EXPECT_EQ(out.event->kind, ServerEvent::Kind::kLoop);
  EXPECT_EQ(out.event->map, map->id());
  EXPECT_EQ(out.event->keyframes, kKeyframes);
  EXPECT_EQ(hooks.loops, std::vector<MapId>{map->id()});
  EXPECT_TRUE(hooks.fusions.empty());
  EXPECT_FALSE(out.forget.valid());
  EXPECT_EQ(out.optimize, options.optimization.global_ba_after_loop ? map->id() : MapId());
  // Nothing had drifted, so closing the loop moves nothing.
  EXPECT_LT((map->map().keyframe(d.query)->camera_center() - before).norm(), 1e-3);
}

TEST(LoopCorrection, AKeyframeAddedWhileThePoseGraphIsSolvedFollowsItsAncestor) {
  const Scene scene = MakeScene();
  MapStack stack{MapOptions{}};
  Map& map = BuildMap(&stack, 1, scene, Sim3())->map();
  const KeyframeId first = KeyframeId::Make(1, 1), last = KeyframeId::Make(1, kKeyframes);
  // The loop moves the first view by 10 cm and 2 deg; the last one holds the gauge (the
  // keyframe added below takes the first view as its parent: all views see every point).
  EssentialGraphCorrection corr;
  for (const auto& kf : map.keyframes()) corr.before.emplace(kf->id(), kf->world_from_cam());
  const Sim3 moved(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.035, Eigen::Vector3d::UnitY())),
                   Eigen::Vector3d(0.1, 0.0, 0.0));
  corr.corrected.emplace(first, moved * Sim3(map.keyframe(first)->world_from_cam()));
  map.keyframe(first)->SetWorldFromCam(opt::RigidPose(corr.corrected.at(first)));  // as CloseLoop does
  corr.loop_connections.emplace_back(first, last);
  corr.fixed = last;
  EssentialGraphProblem graph = BuildEssentialGraphProblem(map, corr);

  // Meanwhile (map unlocked) a keyframe is registered next to the first one, with a new point.
  const auto prev = map.keyframe(first);
  const KeyframeId added = KeyframeId::Make(1, kKeyframes + 1);
  const SE3 added_pose = prev->world_from_cam() * SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.2, 0.0, 0.0));
  map.AddKeyframe(std::make_shared<KeyFrame>(added, prev->stamp_ns() + 50000000, prev->camera_ptr(),
                                             prev->features_ptr(),
                                             std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2)), added_pose));
  for (int i = 0; i < kPoints; ++i) map.AddObservation(added, i, MapPointId::Make(1, i + 1));
  map.UpdateConnections(added);
  const auto kf = map.keyframe(added);
  const auto parent = map.keyframe(kf->parent());
  ASSERT_TRUE(parent) << "the registered keyframe hangs off the spanning tree";
  const Eigen::Vector3d parent_centre = parent->camera_center();
  const SE3 parent_from_added = parent->cam_from_world() * kf->world_from_cam();
  const Eigen::Vector3d point_in_added(0.3, -0.2, 4.0);
  const MapPointId new_point = MapPointId::Make(1, kPoints + 1);
  map.AddMapPoint(std::make_shared<MapPoint>(new_point, kf->world_from_cam() * point_in_added, added,
                                             scene.descriptors[0]));

  const CorrectionResult result = SolveEssentialGraph(std::move(graph), opt::PoseGraphOptions{});
  ASSERT_TRUE(result.ok);
  EXPECT_EQ(result.nodes, kKeyframes) << "the graph was built before the keyframe came";
  const ApplyCorrectionReport rep = ApplyCorrection(&map, result);
  EXPECT_EQ(rep.keyframes, kKeyframes + 1);
  EXPECT_EQ(rep.keyframes_added_meanwhile, 1);
  // The keyframes of the graph end at their optimized poses; the loop moved the last one.
  for (const auto& [id, s] : result.optimized) {
    EXPECT_LT((map.keyframe(id)->camera_center() - s.translation()).norm(), 1e-9);
  }
  EXPECT_GT((map.keyframe(first)->camera_center() - corr.before.at(first).translation()).norm(), 0.02);
  // The added keyframe keeps its pose relative to its parent (which the correction moved), and
  // its point its position in it, both at the scale the correction gave the parent's region.
  EXPECT_GT((parent->camera_center() - parent_centre).norm(), 0.01) << "parent " << parent->id().packed();
  const SE3 after = parent->cam_from_world() * kf->world_from_cam();
  const double scale = result.optimized.at(parent->id()).scale() / result.initial.at(parent->id()).scale();
  EXPECT_LT((after.translation() - scale * parent_from_added.translation()).norm(), 1e-9);
  EXPECT_LT(after.rotation().angularDistance(parent_from_added.rotation()), 1e-9);
  EXPECT_LT((kf->cam_from_world() * map.map_point(new_point)->position() - scale * point_in_added).norm(), 1e-9);
}

TEST(DetectionStage, ADetectionOfAKeyframeNotInTheStackChangesNothing) {
  const Scene scene = MakeScene();
  MapStack stack{MapOptions{}};
  BuildMap(&stack, 1, scene, Sim3());
  BuildMap(&stack, 2, scene, Sim3());
  HookLog hooks;
  ServerOptions options;
  const DetectionStage stage(&stack, options, hooks.Hooks());
  PlaceDetection d = SameView(stack, PlaceDetection::Kind::kFusion, 2, 1, 3, 1.0);
  d.query = KeyframeId::Make(2, 99);
  const DetectionOutcome out = stage.Handle(d, 1.0);
  EXPECT_FALSE(out.event.has_value());
  EXPECT_FALSE(out.refused.empty());
  EXPECT_FALSE(out.optimize.valid());
  EXPECT_FALSE(out.forget.valid());
  EXPECT_TRUE(hooks.fusions.empty());
  EXPECT_EQ(stack.Maps().size(), 2u);
}

}  // namespace
}  // namespace ccm
