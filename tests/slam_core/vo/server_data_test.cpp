// Server data (keyframes and points of "another agent", relative to the agent's reference
// keyframe) integrated into the local map while the VO keeps tracking.
#include <gtest/gtest.h>

#include <set>

#include "tests/slam_core/vo/vo_sim_run.h"

namespace ccm {
namespace {

TEST(ServerData, ForeignKeyframesAndPointsLandWhereTheServerSaysAndTrackingContinues) {
  std::string error;
  const auto sim = testing::LoadSimulation("hall3", &error);
  ASSERT_NE(sim, nullptr) << error;
  sim::SimFrameSource source(sim, 0, 0, 1, 160);
  std::shared_ptr<const CameraModel> camera(MakeCamera(source.intrinsics()));
  AckAll acks;
  AgentVo vo(1, camera, VoOptions{}, &acks, /*synchronous_mapping=*/true);
  for (int i = 0; i < 120; ++i) vo.TrackFrame(*source.Next());
  const VoChanges changes = vo.TakeChanges();
  ASSERT_TRUE(changes.map && changes.reference_kf.valid());
  const auto ref = changes.map->keyframe(changes.reference_kf);
  ASSERT_NE(ref, nullptr);

  // The "server" sends copies of three older keyframes under agent 2's ids, with points.
  ServerMapData data;
  data.reference_kf = ref->id();
  std::vector<std::shared_ptr<KeyFrame>> originals;
  for (const auto& kf : changes.map->keyframes()) {
    if (kf->id() != ref->id() && originals.size() < 3) originals.push_back(kf);
  }
  ASSERT_EQ(originals.size(), 3u);
  std::map<MapPointId, ServerMapPoint> points;
  for (size_t k = 0; k < originals.size(); ++k) {
    const KeyframeId foreign = KeyframeId::Make(2, 1000 + k);
    data.keyframes.push_back({foreign, originals[k]->stamp_ns(), originals[k]->camera_ptr(),
                              originals[k]->features_ptr(), ref->cam_from_world() * originals[k]->world_from_cam()});
    const auto mps = originals[k]->map_points();
    for (size_t i = 0; i < mps.size(); ++i) {
      const auto mp = mps[i].valid() ? changes.map->map_point(mps[i]) : nullptr;
      if (!mp) continue;
      ServerMapPoint& smp = points[mps[i]];
      smp.id = MapPointId::Make(2, mps[i].counter());
      smp.position_ref = ref->cam_from_world() * mp->position();
      smp.observations.emplace_back(foreign, static_cast<int>(i));
    }
  }
  for (auto& [id, smp] : points) data.map_points.push_back(smp);
  data.stamp_ns = 5;
  EXPECT_EQ(vo.Holdings().applied_stamp_ns, 0) << "nothing from the server yet";
  vo.ApplyServerData(data);
  vo.DrainMapping();

  const auto map = vo.map();
  for (size_t k = 0; k < originals.size(); ++k) {
    const auto foreign = map->keyframe(KeyframeId::Make(2, 1000 + k));
    ASSERT_NE(foreign, nullptr) << "foreign keyframe " << k << " not integrated";
    EXPECT_LT((foreign->camera_center() - originals[k]->camera_center()).norm(), 1e-9);
  }
  const AgentVoStats s1 = vo.stats();
  EXPECT_EQ(s1.server.keyframes_added, 3);
  EXPECT_EQ(s1.server.points_added, static_cast<int64_t>(points.size()));
  EXPECT_GE(s1.server.observations_added, static_cast<int64_t>(points.size()));
  // No descriptor travels (protocol 8): each point takes one of its observing keypoints'.
  for (const auto& [id, smp] : points) {
    const auto mp = map->map_point(smp.id);
    ASSERT_NE(mp, nullptr);
    bool from_a_keypoint = false;
    for (const auto& [kf_id, idx] : smp.observations) {
      from_a_keypoint = from_a_keypoint || map->keyframe(kf_id)->features().descriptors[idx] == mp->descriptor();
    }
    EXPECT_TRUE(from_a_keypoint) << "point " << smp.id.counter();
  }
  // Foreign keyframes sharing foreign points are connected in the covisibility graph.
  EXPECT_GT(map->keyframe(KeyframeId::Make(2, 1000))->covisibility().size(), 0u);
  // What the agent reports holding (the server then sends these as poses only).
  const ServerHoldings held = vo.Holdings();
  EXPECT_EQ(held.applied_stamp_ns, 5);
  EXPECT_EQ(std::set<KeyframeId>(held.keyframes.begin(), held.keyframes.end()),
            (std::set<KeyframeId>{KeyframeId::Make(2, 1000), KeyframeId::Make(2, 1001), KeyframeId::Make(2, 1002)}));

  // A pose-only keyframe moves the one held; one no longer held is counted and skipped.
  ServerMapData poses;
  poses.reference_kf = ref->id();
  poses.stamp_ns = 6;
  ServerKeyframe moved;
  moved.id = KeyframeId::Make(2, 1000);
  moved.held = true;
  const SE3 shift(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0, 0));
  moved.ref_from_cam = shift * data.keyframes[0].ref_from_cam;
  ServerKeyframe gone = moved;
  gone.id = KeyframeId::Make(2, 1999);
  poses.keyframes = {moved, gone};
  ServerMapPoint held_point;  // a position only, for a point the agent has
  held_point.id = data.map_points[0].id;
  held_point.held = true;
  held_point.position_ref = data.map_points[0].position_ref + Eigen::Vector3d(0, 0.02, 0);
  ServerMapPoint unknown_point = held_point;
  unknown_point.id = MapPointId::Make(2, 999999);
  poses.map_points = {held_point, unknown_point};
  const size_t observations_before = map->map_point(held_point.id)->num_observations();
  const auto features_before = map->keyframe(moved.id)->features_ptr();
  vo.ApplyServerData(poses);
  vo.DrainMapping();
  const auto moved_kf = map->keyframe(moved.id);
  EXPECT_LT((moved_kf->world_from_cam().translation() -
             (ref->world_from_cam() * moved.ref_from_cam).translation()).norm(), 1e-9);
  EXPECT_EQ(moved_kf->features_ptr(), features_before) << "a pose-only keyframe keeps what the agent has";
  EXPECT_EQ(map->keyframe(gone.id), nullptr);
  EXPECT_EQ(vo.stats().server.keyframes_not_held, 1);
  EXPECT_EQ(vo.stats().server.keyframes_updated, 1);
  EXPECT_EQ(vo.Holdings().applied_stamp_ns, 6);
  EXPECT_LT((map->map_point(held_point.id)->position() - ref->world_from_cam() * held_point.position_ref).norm(), 1e-9);
  EXPECT_EQ(map->map_point(held_point.id)->num_observations(), observations_before) << "observations stay";
  EXPECT_EQ(map->map_point(unknown_point.id), nullptr) << "a position only: nothing to make a point of";
  EXPECT_EQ(vo.stats().server.points_not_held, 1);

  // Nothing received from the server is reported back as an own change.
  const VoChanges after = vo.TakeChanges();
  for (const KeyframeId id : after.keyframes) EXPECT_EQ(id.agent(), 1);

  // Data relative to a keyframe the agent no longer has is stale and dropped.
  ServerMapData stale = data;
  stale.reference_kf = KeyframeId::Make(1, 999999);
  vo.ApplyServerData(stale);
  vo.DrainMapping();
  EXPECT_EQ(vo.stats().server.messages_stale, 1);

  // The VO keeps tracking with the extra data in its map.
  int tracked = 0;
  for (int i = 0; i < 40; ++i) tracked += vo.TrackFrame(*source.Next()).world_from_cam.has_value();
  EXPECT_EQ(tracked, 40);
}

}  // namespace
}  // namespace ccm
