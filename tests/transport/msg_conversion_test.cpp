// Round trips value -> IDL message -> value through the conversion layer for every type,
// both camera models, the IDL bounds on sending, and the camera cache.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <set>

#include <cmath>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/msg_conversion.h"
#include "tests/transport/conversion_test_data.h"

namespace ccm {
namespace {

using conv::FromMsg;
using conv::ToMsg;

void ExpectSamePose(const SE3& a, const SE3& b) {
  EXPECT_LT((a.translation() - b.translation()).norm(), 1e-12);
  EXPECT_LT(a.rotation().angularDistance(b.rotation()), 1e-9);
}

// Intrinsics travel as float.
void ExpectSameCamera(const CameraModel& a, const CameraModel& b) {
  const CameraIntrinsics &x = a.intrinsics(), &y = b.intrinsics();
  EXPECT_EQ(x.type, y.type);
  EXPECT_EQ(x.width_px, y.width_px);
  EXPECT_EQ(x.height_px, y.height_px);
  const std::pair<double, double> values[] = {{x.fx, y.fx}, {x.fy, y.fy}, {x.cx, y.cx}, {x.cy, y.cy}};
  for (const auto& [u, v] : values) EXPECT_EQ(static_cast<float>(u), static_cast<float>(v));
  ASSERT_EQ(x.distortion.size(), y.distortion.size());
  for (size_t i = 0; i < x.distortion.size(); ++i) {
    EXPECT_EQ(static_cast<float>(x.distortion[i]), static_cast<float>(y.distortion[i]));
  }
}

void ExpectSameFeatures(const FrameFeatures& back, const FrameFeatures& sent) {
  ASSERT_EQ(back.size(), sent.size());
  EXPECT_EQ(back.descriptors, sent.descriptors);
  for (size_t i = 0; i < back.size(); ++i) {
    const Keypoint &y = back.keypoints[i], &x = sent.keypoints[i];
    // The wire keeps positions in 1/8 px and angles in 256 steps, not the FAST response.
    const float dangle = std::abs(std::remainder(x.angle_deg - y.angle_deg, 360.0f));
    ASSERT_TRUE(std::abs(x.u - y.u) <= 1.0f / 16 + 1e-4f && std::abs(x.v - y.v) <= 1.0f / 16 + 1e-4f &&
                dangle <= 360.0f / 512 + 1e-3f && y.response == 0.0f && x.level == y.level)
        << "keypoint " << i << ": (" << x.u << ", " << x.v << ", " << x.angle_deg << ") came back as (" << y.u << ", "
        << y.v << ", " << y.angle_deg << ")";
  }
}

void ExpectKeyframeRoundTrip(const CameraIntrinsics& intrinsics) {
  const KeyframeData kf = testing::MakeKeyframeData(3, 12, intrinsics, 600);
  const KeyframeId reference = KeyframeId::Make(4, 2);  // another agent's keyframe the agent tracks
  conv::CameraCache cameras;
  std::string error;
  KeyframeId reference_back;
  const auto back = FromMsg(ToMsg(kf, reference), &cameras, &error, &reference_back);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->id, kf.id);
  EXPECT_EQ(back->segment, kf.segment);
  EXPECT_EQ(back->stamp_ns, kf.stamp_ns);
  EXPECT_EQ(reference_back, reference);
  ExpectSameCamera(*back->camera, *kf.camera);
  EXPECT_EQ(back->pyramid_levels, kf.pyramid_levels);
  EXPECT_FLOAT_EQ(back->pyramid_scale_factor, kf.pyramid_scale_factor);
  ExpectSameFeatures(*back->features, *kf.features);
  EXPECT_EQ(back->point_links, kf.point_links);
  EXPECT_EQ(back->predecessor, kf.predecessor);
  EXPECT_EQ(back->parent, kf.parent);
  ExpectSamePose(back->pred_from_cam, kf.pred_from_cam);
  ExpectSamePose(back->parent_from_cam, kf.parent_from_cam);
  ExpectSamePose(back->segment_from_cam, kf.segment_from_cam);
}

TEST(MsgConversion, KeyframeRoundTripPinholeRadTan) { ExpectKeyframeRoundTrip(testing::PinholeIntrinsics()); }

TEST(MsgConversion, KeyframeRoundTripFisheyeEquidistant) { ExpectKeyframeRoundTrip(testing::FisheyeIntrinsics()); }

TEST(MsgConversion, FirstKeyframeWithoutPredecessorParentOrReference) {
  KeyframeData kf = testing::MakeKeyframeData(2, 1, testing::PinholeIntrinsics(), 50);
  kf.parent = KeyframeId::Invalid();
  kf.point_links.clear();
  KeyframeId reference = KeyframeId::Make(2, 5);
  std::string error;
  const auto back = FromMsg(ToMsg(kf, KeyframeId::Invalid()), nullptr, &error, &reference);
  ASSERT_TRUE(back) << error;
  EXPECT_FALSE(back->predecessor.valid());
  EXPECT_FALSE(back->parent.valid());
  EXPECT_FALSE(reference.valid());
  EXPECT_TRUE(back->point_links.empty());
}

TEST(MsgConversion, AnchorOnlyKeyframeRoundTripCarriesPosesOnly) {
  KeyframeData kf = testing::MakeKeyframeData(3, 12, testing::PinholeIntrinsics(), 0);
  kf.point_links.clear();
  kf.anchor_only = true;
  msg::KeyframeFull m = ToMsg(kf, KeyframeId::Make(3, 11));
  EXPECT_TRUE(m.keypoints().empty());
  EXPECT_LT(msg::KeyframeFullPubSubType().getSerializedSizeProvider(&m)(), 400u)
      << "an anchor must cost a few hundred bytes, not a keyframe's ~41 kB";
  std::string error;
  const auto back = FromMsg(m, nullptr, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_TRUE(back->anchor_only);
  EXPECT_EQ(back->features->size(), 0u);
  EXPECT_EQ(back->parent, kf.parent);
  ExpectSamePose(back->parent_from_cam, kf.parent_from_cam);
  ExpectSamePose(back->pred_from_cam, kf.pred_from_cam);
  const auto full = FromMsg(ToMsg(testing::MakeKeyframeData(3, 12, testing::PinholeIntrinsics(), 50), {}), nullptr, &error);
  ASSERT_TRUE(full) << error;
  EXPECT_FALSE(full->anchor_only);
}

TEST(MsgConversion, KeyframeBeyondTheKeypointBoundLosesTheRestAndItsLinks) {
  KeyframeData kf = testing::MakeKeyframeData(1, 5, testing::PinholeIntrinsics(), msg::kMaxKeypoints + 300);
  const msg::KeyframeFull m = ToMsg(kf, KeyframeId::Invalid());
  EXPECT_EQ(m.keypoints().size(), msg::kMaxKeypoints);
  EXPECT_EQ(m.descriptors().size(), msg::kMaxKeypoints);
  for (auto index : m.own_mp_keypoint_index()) EXPECT_LT(index, msg::kMaxKeypoints);
  for (auto index : m.other_mp_keypoint_index()) EXPECT_LT(index, msg::kMaxKeypoints);
  std::string error;
  EXPECT_TRUE(FromMsg(m, nullptr, &error)) << error;
}

TEST(MsgConversion, MapPointRoundTripInABatch) {
  const MapPointData mp = testing::MakeMapPointData(6, 77);
  msg::MapPointBatch batch = conv::PointBatch(6, mp.segment);
  batch.points().push_back(ToMsg(mp));
  std::string error;
  const auto segment = conv::BatchSegment(batch, &error);
  ASSERT_TRUE(segment) << error;
  EXPECT_EQ(*segment, mp.segment);
  const auto back = FromMsg(batch.points()[0], batch.agent_id(), *segment, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->id, mp.id);
  EXPECT_EQ(back->segment, mp.segment);
  EXPECT_EQ(back->reference_kf, mp.reference_kf);
  EXPECT_LT((back->position_ref - mp.position_ref).norm(), 1e-6 * mp.position_ref.norm());  // float
  EXPECT_EQ(back->descriptor, OrbDescriptor{}) << "not on the wire: the server derives it from the observations";
  EXPECT_EQ(back->observations, mp.observations);
}

TEST(MsgConversion, MapPointBeyondTheObservationBoundLosesTheRest) {
  const MapPointData mp = testing::MakeMapPointData(6, 78, msg::kMaxObservations + 10);
  EXPECT_EQ(ToMsg(mp).obs_kf_offsets().size(), msg::kMaxObservations);
  std::string error;
  EXPECT_TRUE(FromMsg(ToMsg(mp), 6, mp.segment, &error)) << error;
}

TEST(MsgConversion, KeyframeUpdateRoundTrip) {
  const KeyframePoseUpdate u = testing::MakeKeyframePoseUpdate(9, 40);
  std::string error;
  const auto back = FromMsg(ToMsg(u), &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->id, u.id);
  EXPECT_EQ(back->segment, u.segment);
  EXPECT_EQ(back->predecessor, u.predecessor);
  EXPECT_EQ(back->parent, u.parent);
  ExpectSamePose(back->pred_from_cam, u.pred_from_cam);
  ExpectSamePose(back->parent_from_cam, u.parent_from_cam);
}

TEST(MsgConversion, MapPointUpdateRoundTripCarriesTheSegment) {
  const MapPointPositionUpdate u = testing::MakeMapPointPositionUpdate(9, 41);
  std::string error;
  msg::MapPointUpdateBatch batch = conv::PointUpdateBatch(9, MapId::Make(9, 3));
  batch.updates().push_back(ToMsg(u));
  const auto segment = conv::BatchSegment(batch, &error);
  ASSERT_TRUE(segment) << error;
  EXPECT_EQ(*segment, MapId::Make(9, 3));
  const auto back = FromMsg(batch.updates()[0], batch.agent_id(), &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->id, u.id);
  EXPECT_EQ(back->reference_kf, u.reference_kf);
  EXPECT_EQ(back->position_ref, u.position_ref);  // exactly representable in float
  // A segment that cannot travel is sent as 0, which receivers reject.
  EXPECT_EQ(conv::PointUpdateBatch(9, MapId::Make(9, std::uint64_t{1} << 40)).segment_counter(), 0u);
  EXPECT_EQ(conv::PointBatch(9, MapId::Make(8, 3)).segment_counter(), 0u);
  EXPECT_FALSE(conv::BatchSegment(conv::PointBatch(9, MapId::Make(8, 3)), &error));
  EXPECT_EQ(error, "map point batch: segment counter is 0");
}

TEST(MsgConversion, ServerMessageRoundTrip) {
  const ServerMapData data = testing::MakeServerMapData(2, 5, 800, 400);
  const std::vector<KeyframeId> acked_kfs = {KeyframeId::Make(2, 1), KeyframeId::Make(2, 2)};
  const std::vector<MapPointId> acked_mps = {MapPointId::Make(2, 10)};
  conv::CameraCache cameras;
  std::string error;
  const auto back = FromMsg(ToMsg(2, 123456789, acked_kfs, acked_mps, &data), 2, &cameras, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->stamp_ns, 123456789);
  EXPECT_EQ(back->acked_kfs, acked_kfs);
  EXPECT_EQ(back->acked_mps, acked_mps);
  ASSERT_TRUE(back->data);
  EXPECT_EQ(back->data->reference_kf, data.reference_kf);
  ASSERT_EQ(back->data->keyframes.size(), data.keyframes.size());
  for (size_t i = 0; i < data.keyframes.size(); ++i) {
    const ServerKeyframe &a = back->data->keyframes[i], &b = data.keyframes[i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.stamp_ns, b.stamp_ns);
    ExpectSameCamera(*a.camera, *b.camera);
    ExpectSameFeatures(*a.features, *b.features);
    ExpectSamePose(a.ref_from_cam, b.ref_from_cam);
  }
  EXPECT_EQ(cameras.size(), 2u);  // two calibrations among five keyframes
  ASSERT_EQ(back->data->map_points.size(), data.map_points.size());
  for (size_t i = 0; i < data.map_points.size(); ++i) {
    const ServerMapPoint &a = back->data->map_points[i], &b = data.map_points[i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_LT((a.position_ref - b.position_ref).norm(), 1e-6 * b.position_ref.norm());
    EXPECT_EQ(a.observations, b.observations);
  }
}

TEST(MsgConversion, ServerMessageWithAcksOnlyHasNoMapData) {
  std::string error;
  const auto back = FromMsg(ToMsg(4, 1, {KeyframeId::Make(4, 3)}, {}, nullptr), 4, nullptr, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->acked_kfs, std::vector<KeyframeId>{KeyframeId::Make(4, 3)});
  EXPECT_FALSE(back->data);
}

TEST(MsgConversion, ServerMessageRespectsEveryIdlBoundAndSerializes) {
  ServerMapData data = testing::MakeServerMapData(1, msg::kMaxKeyframesPerServerMsg + 4, 50,
                                                  msg::kMaxMapPointsPerServerMsg + 100);
  for (int i = 0; i < 100; ++i) data.map_points[0].observations.emplace_back(KeyframeId::Make(1, 200 + i), i);
  std::vector<KeyframeId> acks;
  for (uint64_t i = 1; i <= msg::kMaxAcks + 50; ++i) acks.push_back(KeyframeId::Make(1, i));
  msg::ServerToAgent m = ToMsg(1, 0, acks, {}, &data);
  EXPECT_EQ(m.acked_kf_ids().size(), msg::kMaxAcks);
  EXPECT_EQ(m.keyframes().size(), msg::kMaxKeyframesPerServerMsg);
  EXPECT_EQ(m.map_points().size(), msg::kMaxMapPointsPerServerMsg);
  EXPECT_EQ(m.map_points()[0].obs_kf_ids().size(), msg::kMaxObservations);
  // Observations of the keyframes left out are left out too.
  const KeyframeId left_out = data.keyframes.back().id;
  for (const auto& mp : m.map_points()) {
    for (auto id : mp.obs_kf_ids()) ASSERT_NE(id, left_out.packed());
  }
  msg::ServerToAgentPubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&m)());
  EXPECT_TRUE(type.serialize(&m, &payload));
  std::string error;
  EXPECT_TRUE(FromMsg(m, 1, nullptr, &error)) << error;
}

TEST(MsgConversion, ServerMessageLeavesOutWhatTheAgentWouldRejectInsteadOfLosingTheMessage) {
  // A point the server holds at near-infinite depth, a keyframe placed far off: the agent's
  // FromMsg rejects either (beyond 1e6 m), and with it every other keyframe and point.
  ServerMapData data = testing::MakeServerMapData(1, 4, 50, 30);
  data.map_points[3].position_ref = Eigen::Vector3d(0, 0, 3e6);
  data.map_points[5].position_ref.x() = std::numeric_limits<double>::quiet_NaN();
  const KeyframeId far = data.keyframes[2].id;
  data.keyframes[2].ref_from_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2e6, 0, 0));
  std::string error;
  const auto back = FromMsg(ToMsg(1, 0, {}, {}, &data), 1, nullptr, &error);
  ASSERT_TRUE(back && back->data) << error;
  EXPECT_EQ(back->data->keyframes.size(), 3u);
  EXPECT_EQ(back->data->map_points.size(), 28u);
  for (const ServerKeyframe& kf : back->data->keyframes) EXPECT_NE(kf.id, far);
  for (const ServerMapPoint& mp : back->data->map_points) {
    EXPECT_NE(mp.id, data.map_points[3].id);
    EXPECT_NE(mp.id, data.map_points[5].id);
    for (const auto& [kf, index] : mp.observations) EXPECT_NE(kf, far);
  }
}

TEST(MsgConversion, HeldKeyframesTravelAsPosesOnlyAndTheirObservationsStay) {
  // Downlink deltas: keyframes the agent holds go as id + pose (a few dozen bytes instead of
  // tens of kB); points keep their observations of them (the agent checks the index).
  ServerMapData data = testing::MakeServerMapData(1, 4, 500, 40);
  data.keyframes[1].held = data.keyframes[3].held = true;
  const ServerMapData all_full = testing::MakeServerMapData(1, 4, 500, 40);
  msg::ServerToAgent full_msg = ToMsg(1, 7, {}, {}, &all_full);
  msg::ServerToAgent m = ToMsg(1, 7, {}, {}, &data);
  EXPECT_EQ(m.keyframes().size(), 2u);
  EXPECT_EQ(m.held_keyframes().size(), 2u);
  msg::ServerToAgentPubSubType type;
  const auto size = [&](msg::ServerToAgent& x) { return type.getSerializedSizeProvider(&x)(); };
  EXPECT_LT(size(m), size(full_msg) * 0.7) << "two of four keyframes' features left out";
  std::string error;
  const auto back = FromMsg(m, 1, nullptr, &error);
  ASSERT_TRUE(back && back->data) << error;
  EXPECT_EQ(back->data->stamp_ns, 7);
  ASSERT_EQ(back->data->keyframes.size(), 4u);
  std::set<KeyframeId> held_back;
  for (const ServerKeyframe& kf : back->data->keyframes) {
    if (!kf.held) {
      EXPECT_TRUE(kf.features && kf.camera);
      continue;
    }
    EXPECT_FALSE(kf.features || kf.camera);
    held_back.insert(kf.id);
    const auto sent = std::find_if(data.keyframes.begin(), data.keyframes.end(), [&](const auto& k) { return k.id == kf.id; });
    ASSERT_NE(sent, data.keyframes.end());
    ExpectSamePose(kf.ref_from_cam, sent->ref_from_cam);
  }
  EXPECT_EQ(held_back, (std::set<KeyframeId>{data.keyframes[1].id, data.keyframes[3].id}));
  ASSERT_EQ(back->data->map_points.size(), data.map_points.size());
  for (size_t i = 0; i < data.map_points.size(); ++i) EXPECT_EQ(back->data->map_points[i].observations, data.map_points[i].observations);
  // A held keyframe sent twice, or also in full, is refused.
  msg::ServerToAgent twice = m;
  twice.held_keyframes().push_back(twice.held_keyframes()[0]);
  EXPECT_FALSE(FromMsg(twice, 1, nullptr, &error));
  EXPECT_NE(error.find("twice"), std::string::npos) << error;
}

TEST(MsgConversion, HeldPointsTravelAsPositionsOnly) {
  ServerMapData data = testing::MakeServerMapData(1, 3, 200, 50);
  for (int i = 0; i < 30; ++i) data.map_points[i].held = true;
  msg::ServerToAgent m = ToMsg(1, 9, {}, {}, &data);
  EXPECT_EQ(m.map_points().size(), 20u);
  EXPECT_EQ(m.held_map_points().size(), 30u);
  std::string error;
  const auto back = FromMsg(m, 1, nullptr, &error);
  ASSERT_TRUE(back && back->data) << error;
  ASSERT_EQ(back->data->map_points.size(), 50u);
  int held = 0;
  for (const ServerMapPoint& p : back->data->map_points) {
    const auto sent = std::find_if(data.map_points.begin(), data.map_points.end(), [&](const auto& q) { return q.id == p.id; });
    ASSERT_NE(sent, data.map_points.end());
    EXPECT_EQ(p.held, sent->held);
    EXPECT_LT((p.position_ref - sent->position_ref).norm(), 1e-5 * sent->position_ref.norm());
    if (p.held) {
      ++held;
      EXPECT_TRUE(p.observations.empty());
    } else {
      EXPECT_EQ(p.observations, sent->observations);
    }
  }
  EXPECT_EQ(held, 30);
  msg::ServerToAgent twice = m;
  msg::ServerMapPointPosition again = twice.held_map_points()[0];
  again.id(twice.map_points()[0].id());  // also sent in full
  twice.held_map_points().push_back(again);
  EXPECT_FALSE(FromMsg(twice, 1, nullptr, &error));
  EXPECT_NE(error.find("twice"), std::string::npos) << error;
}

TEST(MsgConversion, HeldPointsOfTheReceivingAgentDoNotTravel) {
  // Its own points the agent keeps as its VO has them: a position would be ignored.
  ServerMapData data = testing::MakeServerMapData(1, 3, 200, 50);
  for (int i = 0; i < 30; ++i) data.map_points[i].held = true;
  for (int i = 0; i < 10; ++i) data.map_points[i].id = MapPointId::Make(1, 7000 + i);  // held, own
  data.map_points[40].id = MapPointId::Make(1, 7100);                                   // full, own
  const msg::ServerToAgent m = ToMsg(1, 9, {}, {}, &data);
  EXPECT_EQ(m.held_map_points().size(), 20u);
  EXPECT_EQ(m.map_points().size(), 20u) << "own points in full still bring their observations";
  for (const auto& h : m.held_map_points()) EXPECT_NE(MapPointId(h.id()).agent(), 1);
}

TEST(MsgConversion, StatusCarriesTheAgentsHoldings) {
  msg::AgentStatus m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(3);
  m.server_data_stamp_ns(42);
  m.held_server_kf_ids().push_back(KeyframeId::Make(1, 5).packed());
  m.held_server_kf_ids().push_back(KeyframeId::Make(3, 2).packed());
  std::string error;
  const auto st = conv::FromMsg(m, &error);
  ASSERT_TRUE(st) << error;
  EXPECT_EQ(st->holdings.applied_stamp_ns, 42);
  EXPECT_EQ(st->holdings.keyframes, (std::vector<KeyframeId>{KeyframeId::Make(1, 5), KeyframeId::Make(3, 2)}));
  m.held_server_kf_ids().push_back(0);
  EXPECT_FALSE(conv::FromMsg(m, &error)) << "id 0 is no keyframe";
}

TEST(MsgConversion, CameraCacheSharesOneModelPerCalibrationAndStaysBounded) {
  conv::CameraCache cameras(2);
  std::string error;
  const auto a = cameras.Get(testing::PinholeIntrinsics(), &error);
  const auto b = cameras.Get(testing::PinholeIntrinsics(), &error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a.get(), b.get());
  const auto fisheye = cameras.Get(testing::FisheyeIntrinsics(), &error);
  EXPECT_NE(fisheye.get(), a.get());
  CameraIntrinsics third = testing::PinholeIntrinsics();
  third.fx += 1.0;
  cameras.Get(third, &error);
  EXPECT_EQ(cameras.size(), 2u);
  // The pinhole model was least recently used: it went, and a holder keeps it alive.
  EXPECT_NE(cameras.Get(testing::PinholeIntrinsics(), &error).get(), a.get());
  CameraIntrinsics bad = third;
  bad.fx = -1;
  EXPECT_FALSE(cameras.Get(bad, &error));
  EXPECT_EQ(error, "fx and fy must be > 0");
}

TEST(MsgConversion, ReasonKindDropsTheNumbers) {
  EXPECT_EQ(conv::ReasonKind("keyframe: keypoint 12 outside the image"), "keyframe: keypoint # outside the image");
  EXPECT_EQ(conv::ReasonKind("map point: id 3:17 is invalid"), "map point: id #:# is invalid");
}

}  // namespace
}  // namespace ccm
