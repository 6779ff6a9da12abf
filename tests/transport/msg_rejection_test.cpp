// Every validation rule of the conversion layer's FromMsg, one expectation each, asserting
// the reason text: a valid message is built from value-type data, one field is broken.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

#include "runtime_common/msg_conversion.h"
#include "tests/transport/conversion_test_data.h"

namespace ccm {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

template <typename Msg>
using Mutation = std::function<void(Msg&)>;

std::string KeyframeRejection(const Mutation<msg::KeyframeFull>& mutate) {
  msg::KeyframeFull m =
      conv::ToMsg(testing::MakeKeyframeData(3, 12, testing::PinholeIntrinsics(), 100), KeyframeId::Make(3, 11));
  mutate(m);
  std::string error;
  return conv::FromMsg(m, nullptr, &error) ? "accepted" : error;
}

// A batch of one point (the batch carries version, agent and segment).
std::string MapPointRejection(const Mutation<msg::MapPointBatch>& mutate) {
  const MapPointData mp = testing::MakeMapPointData(3, 40);
  msg::MapPointBatch m = conv::PointBatch(3, mp.segment);
  m.points().push_back(conv::ToMsg(mp));
  mutate(m);
  std::string error;
  const auto segment = conv::BatchSegment(m, &error);
  return segment && conv::FromMsg(m.points()[0], m.agent_id(), *segment, &error) ? "accepted" : error;
}

std::string KeyframeUpdateRejection(const Mutation<msg::KeyframeUpdate>& mutate) {
  msg::KeyframeUpdate m = conv::ToMsg(testing::MakeKeyframePoseUpdate(3, 20));
  mutate(m);
  std::string error;
  return conv::FromMsg(m, &error) ? "accepted" : error;
}

std::string MapPointUpdateRejection(const Mutation<msg::MapPointUpdateBatch>& mutate) {
  msg::MapPointUpdateBatch m = conv::PointUpdateBatch(3, MapId::Make(3, 1));
  m.updates().push_back(conv::ToMsg(testing::MakeMapPointPositionUpdate(3, 21)));
  mutate(m);
  std::string error;
  const auto segment = conv::BatchSegment(m, &error);
  return segment && conv::FromMsg(m.updates()[0], m.agent_id(), &error) ? "accepted" : error;
}

// For agent 1: acks, 3 keyframes of agent 2 with 50 features, 20 points.
std::string ServerRejection(const Mutation<msg::ServerToAgent>& mutate) {
  const ServerMapData data = testing::MakeServerMapData(1, 3, 50, 20);
  msg::ServerToAgent m = conv::ToMsg(1, 5, {KeyframeId::Make(1, 4)}, {MapPointId::Make(1, 8)}, &data);
  mutate(m);
  std::string error;
  return conv::FromMsg(m, 1, nullptr, &error) ? "accepted" : error;
}

uint64_t Kf(AgentId agent, uint64_t counter) { return KeyframeId::Make(agent, counter).packed(); }

TEST(MsgRejection, Keyframe) {
  auto r = KeyframeRejection;
  EXPECT_EQ(r([](auto&) {}), "accepted");
  EXPECT_EQ(r([](auto& m) { m.protocol_version(1); }), "keyframe: protocol version 1, expected " + std::to_string(msg::kProtocolVersion));
  EXPECT_EQ(r([](auto& m) { m.id(Kf(4, 12)); }), "keyframe: keyframe id 4:12 belongs to agent 4, not to sender 3");
  EXPECT_EQ(r([](auto& m) { m.agent_id(5); }), "keyframe: keyframe id 3:12 belongs to agent 3, not to sender 5");
  EXPECT_EQ(r([](auto& m) { m.id(Kf(3, 0)); }), "keyframe: keyframe id 3:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.segment_id(MapId::Make(7, 1).packed()); }),
            "keyframe: segment id 7:1 belongs to agent 7, not to sender 3");
  EXPECT_EQ(r([](auto& m) { m.predecessor_id(Kf(2, 11)); }), "keyframe: predecessor of another agent");
  EXPECT_EQ(r([](auto& m) { m.predecessor_id(Kf(3, 12)); }), "keyframe: bad predecessor id");  // exchange validator
  EXPECT_EQ(r([](auto& m) { m.parent_id(Kf(4, 0)); }), "keyframe: parent id 4:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.parent_id(Kf(3, 12)); }), "keyframe: bad parent id");
  EXPECT_EQ(r([](auto& m) { m.ref_kf_id(Kf(6, 0)); }), "keyframe: reference keyframe id 6:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.stamp_ns(-1); }), "keyframe: negative stamp");
}

TEST(MsgRejection, KeyframeCamera) {
  auto r = KeyframeRejection;
  EXPECT_EQ(r([](auto& m) { m.camera().model(7); }), "keyframe: camera: unknown model 7");
  EXPECT_EQ(r([](auto& m) { m.camera().fx(-458.0f); }), "keyframe: camera: fx and fy must be > 0");
  EXPECT_EQ(r([](auto& m) { m.camera().fy(kNaN); }), "keyframe: camera: fx and fy must be > 0");
  EXPECT_EQ(r([](auto& m) { m.camera().width_px(0); }), "keyframe: camera: image size must be positive, got 0x480");
  EXPECT_EQ(r([](auto& m) { m.camera().model(1); }),
            "keyframe: camera: equidistant needs 4 distortion coefficients (k1..k4), got 5");
  EXPECT_EQ(r([](auto& m) { m.camera().distortion().resize(9); }), "keyframe: camera: 9 distortion coefficients");
  EXPECT_EQ(r([](auto& m) { m.camera().distortion()[1] = kNaN; }),
            "keyframe: camera: distortion coefficients must be finite");
  EXPECT_EQ(r([](auto& m) { m.camera().fx(3e5f); }), "keyframe: camera: focal length beyond 1e5 px");
  EXPECT_EQ(r([](auto& m) { m.camera().cx(-1e4f); }), "keyframe: camera: principal point far outside the image");
  EXPECT_EQ(r([](auto& m) { m.camera().distortion()[0] = 1e6f; }), "keyframe: camera: distortion coefficient beyond 1e4");
}

TEST(MsgRejection, KeyframeFeaturesAndLinks) {
  auto r = KeyframeRejection;
  EXPECT_EQ(r([](auto& m) { m.pyramid_levels(0); }), "keyframe: pyramid levels 0 not in 1..16");
  EXPECT_EQ(r([](auto& m) { m.pyramid_scale_factor(3.0f); }), "keyframe: pyramid scale factor not in (1, 2]");
  EXPECT_EQ(r([](auto& m) { m.pyramid_scale_factor(kNaN); }), "keyframe: pyramid scale factor not in (1, 2]");
  EXPECT_EQ(r([](auto& m) { m.descriptors().pop_back(); }), "keyframe: 100 keypoints but 99 descriptors");
  EXPECT_EQ(r([](auto& m) {
              m.keypoints().resize(msg::kMaxKeypoints + 1);
              m.descriptors().resize(msg::kMaxKeypoints + 1);
            }),
            "keyframe: 4001 keypoints (limit 4000)");
  EXPECT_EQ(r([](auto& m) { m.keypoints()[12].x_eighth_px(8 * 800); }), "keyframe: keypoint 12 outside the image");
  EXPECT_EQ(r([](auto& m) { m.keypoints()[12].y_eighth_px(65535); }), "keyframe: keypoint 12 outside the image");
  EXPECT_EQ(r([](auto& m) { m.keypoints()[12].octave(8); }),
            "keyframe: keypoint 12: octave 8 not below pyramid levels 8");
  // 34 links: 17 to the agent's own points (offsets from a base), 17 to agent 4's (full ids).
  EXPECT_EQ(r([](auto& m) { m.other_mp_ids().pop_back(); }), "keyframe: 17 link indices but 16 link ids");
  EXPECT_EQ(r([](auto& m) { m.own_mp_offsets().pop_back(); }), "keyframe: 17 own link indices but 16 offsets");
  EXPECT_EQ(r([](auto& m) { m.other_mp_keypoint_index()[2] = 100; }),
            "keyframe: point link 2: keypoint index 100 out of range");
  EXPECT_EQ(r([](auto& m) { m.own_mp_keypoint_index()[2] = 100; }),
            "keyframe: own point link 2: keypoint index 100 out of range");
  EXPECT_EQ(r([](auto& m) { m.other_mp_ids()[2] = 0; }), "keyframe: point link 2: map point id 0:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.own_mp_base(MapPointId::Make(4, 1000).packed()); }),
            "keyframe: point link base id 4:1000 belongs to agent 4, not to sender 3");
  EXPECT_EQ(r([](auto& m) { m.own_mp_base(0); }), "keyframe: point link base id 0:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.own_mp_base(MapPointId::Make(3, MapPointId::kCounterMask - 5).packed()); }),
            "keyframe: own point link 1: offset 6 out of range");  // counter beyond 48 bits
  EXPECT_EQ(r([](auto& m) { m.other_mp_keypoint_index()[0] = m.own_mp_keypoint_index()[1]; }),
            "keyframe: point link 2: keypoint linked twice");  // exchange validator, keypoint order
  // An anchor carries poses only, and must name the keyframe it duplicates.
  EXPECT_EQ(r([](auto& m) { m.anchor_only(true); }), "keyframe: anchor-only keyframe with features or point links");
  EXPECT_EQ(r([](auto& m) {
              m.anchor_only(true);
              m.keypoints().clear();
              m.descriptors().clear();
              m.own_mp_keypoint_index().clear();
              m.own_mp_offsets().clear();
              m.other_mp_keypoint_index().clear();
              m.other_mp_ids().clear();
              m.parent_id(0);
            }),
            "keyframe: anchor-only keyframe without the keyframe it duplicates (parent)");
}

TEST(MsgRejection, KeyframePoses) {
  auto r = KeyframeRejection;
  EXPECT_EQ(r([](auto& m) { m.pred_from_this().tx(kInf); }), "keyframe: pred_from_this: non-finite value");
  EXPECT_EQ(r([](auto& m) { m.parent_from_this().qw(kNaN); }), "keyframe: parent_from_this: non-finite value");
  EXPECT_EQ(r([](auto& m) { m.parent_from_this().tz(2e6); }), "keyframe: parent_from_this: translation beyond 1e6 m");
  EXPECT_EQ(r([](auto& m) {
              auto& p = m.segment_from_this();
              p.qx(0); p.qy(0); p.qz(0); p.qw(1.002);
            }),
            "keyframe: segment_from_this: quaternion is not a unit quaternion");
  EXPECT_EQ(r([](auto& m) {
              auto& p = m.segment_from_this();
              p.qx(0); p.qy(0); p.qz(0); p.qw(0);
            }),
            "keyframe: segment_from_this: quaternion is not a unit quaternion");
  // Within the tolerance: accepted and normalized.
  msg::KeyframeFull m = conv::ToMsg(testing::MakeKeyframeData(3, 12, testing::PinholeIntrinsics(), 10), {});
  m.pred_from_this().qx(0); m.pred_from_this().qy(0); m.pred_from_this().qz(0); m.pred_from_this().qw(1.0005);
  std::string error;
  const auto kf = conv::FromMsg(m, nullptr, &error);
  ASSERT_TRUE(kf) << error;
  EXPECT_DOUBLE_EQ(kf->pred_from_cam.rotation().norm(), 1.0);
}

TEST(MsgRejection, MapPoint) {
  auto r = MapPointRejection;
  EXPECT_EQ(r([](auto&) {}), "accepted");
  EXPECT_EQ(r([](auto& m) { m.protocol_version(2); }), "map point batch: protocol version 2, expected " + std::to_string(msg::kProtocolVersion));
  EXPECT_EQ(r([](auto& m) { m.points()[0].id(MapPointId::Make(4, 40).packed()); }),
            "map point: map point id 4:40 belongs to agent 4, not to sender 3");
  EXPECT_EQ(r([](auto& m) { m.segment_counter(0); }), "map point batch: segment counter is 0");
  EXPECT_EQ(r([](auto& m) { m.points()[0].ref_kf_id(Kf(2, 3)); }),
            "map point: reference keyframe id 2:3 belongs to agent 2, not to sender 3");
  EXPECT_EQ(r([](auto& m) { m.points()[0].y_ref(kNaN); }), "map point: position: non-finite value");
  EXPECT_EQ(r([](auto& m) { m.points()[0].z_ref(3e7f); }), "map point: position beyond 1e6 m");
  EXPECT_EQ(r([](auto& m) { m.points()[0].obs_kf_offsets().pop_back(); }), "map point: 4 observing keyframes but 5 keypoint indices");
  EXPECT_EQ(r([](auto& m) {
              m.points()[0].obs_kf_offsets().resize(65, 0);
              m.points()[0].obs_keypoint_index().resize(65, 1);
            }),
            "map point: 65 observations (limit 64)");
  // The reference keyframe is 3:3: an offset of -3 names counter 0.
  EXPECT_EQ(r([](auto& m) { m.points()[0].obs_kf_offsets()[1] = -3; }), "map point: observation 1: keyframe offset -3 out of range");
  EXPECT_EQ(r([](auto& m) { m.points()[0].ref_kf_id(Kf(3, KeyframeId::kCounterMask)); }),
            "map point: observation 1: keyframe offset 1 out of range");
  EXPECT_EQ(r([](auto& m) { m.points()[0].obs_keypoint_index()[1] = 4000; }),
            "map point: observation 1: keypoint index 4000 out of range");
}

TEST(MsgRejection, Updates) {
  auto k = KeyframeUpdateRejection;
  EXPECT_EQ(k([](auto&) {}), "accepted");
  EXPECT_EQ(k([](auto& m) { m.protocol_version(0); }), "keyframe update: protocol version 0, expected " + std::to_string(msg::kProtocolVersion));
  EXPECT_EQ(k([](auto& m) { m.id(Kf(1, 20)); }), "keyframe update: keyframe id 1:20 belongs to agent 1, not to sender 3");
  EXPECT_EQ(k([](auto& m) { m.segment_counter(0); }), "keyframe update: segment counter is 0");
  EXPECT_EQ(k([](auto& m) { m.predecessor_id(Kf(2, 19)); }), "keyframe update: predecessor of another agent");
  EXPECT_EQ(k([](auto& m) { m.parent_id(Kf(2, 0)); }), "keyframe update: parent id 2:0 is invalid");
  EXPECT_EQ(k([](auto& m) {
              auto& p = m.pred_from_this();
              p.qx(0.7); p.qy(0); p.qz(0); p.qw(0.7);
            }),
            "keyframe update: pred_from_this: quaternion is not a unit quaternion");
  EXPECT_EQ(k([](auto& m) { m.parent_from_this().ty(-kInf); }), "keyframe update: parent_from_this: non-finite value");

  auto p = MapPointUpdateRejection;
  EXPECT_EQ(p([](auto&) {}), "accepted");
  EXPECT_EQ(p([](auto& m) { m.protocol_version(1); }), "map point update batch: protocol version 1, expected " + std::to_string(msg::kProtocolVersion));
  EXPECT_EQ(p([](auto& m) { m.updates()[0].id(MapPointId::Make(3, 0).packed()); }), "map point update: map point id 3:0 is invalid");
  EXPECT_EQ(p([](auto& m) { m.segment_counter(0); }), "map point update batch: segment counter is 0");
  EXPECT_EQ(p([](auto& m) { m.updates()[0].ref_kf_id(Kf(9, 4)); }),
            "map point update: reference keyframe id 9:4 belongs to agent 9, not to sender 3");
  EXPECT_EQ(p([](auto& m) { m.updates()[0].x_ref(std::numeric_limits<float>::infinity()); }),
            "map point update: position: non-finite value");
}

TEST(MsgRejection, ServerMessage) {
  auto r = ServerRejection;
  EXPECT_EQ(r([](auto&) {}), "accepted");
  EXPECT_EQ(r([](auto& m) { m.protocol_version(1); }), "server message: protocol version 1, expected " + std::to_string(msg::kProtocolVersion));
  EXPECT_EQ(r([](auto& m) { m.agent_id(2); }), "server message: addressed to agent 2, not 1");
  EXPECT_EQ(r([](auto& m) { m.server_epoch(0); }), "server message: server epoch 0");
  EXPECT_EQ(r([](auto& m) { m.acked_kf_ids().push_back(Kf(2, 5)); }),
            "server message: acked keyframe id 2:5 belongs to agent 2, not to sender 1");
  EXPECT_EQ(r([](auto& m) { m.acked_mp_ids()[0] = 0; }), "server message: acked map point id 0:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.acked_kf_ids().resize(msg::kMaxAcks + 1, Kf(1, 1)); }), "server message: too many acks");
  EXPECT_EQ(r([](auto& m) { m.keyframes().resize(msg::kMaxKeyframesPerServerMsg + 1); }),
            "server message: 17 keyframes (limit 16)");
  EXPECT_EQ(r([](auto& m) { m.map_points().resize(msg::kMaxMapPointsPerServerMsg + 1); }),
            "server message: 4097 map points (limit 4096)");
  EXPECT_EQ(r([](auto& m) { m.ref_kf_id(0); }), "server message: reference keyframe id 0:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.keyframes()[1].id(0); }), "server message: keyframe 1: keyframe id 0:0 is invalid");
  EXPECT_EQ(r([](auto& m) { m.keyframes()[2].id(m.keyframes()[0].id()); }), "server message: keyframe 2: id sent twice");
  EXPECT_EQ(r([](auto& m) { m.keyframes()[1].camera().cy(kNaN); }),
            "server message: keyframe 1: camera: cx and cy must be finite");
  EXPECT_EQ(r([](auto& m) { m.keyframes()[1].pyramid_levels(17); }),
            "server message: keyframe 1: pyramid levels 17 not in 1..16");
  EXPECT_EQ(r([](auto& m) { m.keyframes()[0].keypoints()[3].x_eighth_px(60000); }),
            "server message: keyframe 0: keypoint 3 outside the image");
  EXPECT_EQ(r([](auto& m) { m.keyframes()[0].ref_from_this().qz(2.0); }),
            "server message: keyframe 0: ref_from_this: quaternion is not a unit quaternion");
  EXPECT_EQ(r([](auto& m) { m.map_points()[3].id(m.map_points()[2].id()); }), "server message: map point 3: id sent twice");
  EXPECT_EQ(r([](auto& m) { m.map_points()[3].x_ref(kNaN); }),
            "server message: map point 3: position: non-finite value");
  EXPECT_EQ(r([](auto& m) { m.map_points()[3].obs_keypoint_index().pop_back(); }),
            "server message: map point 3: 2 observing keyframes but 1 keypoint indices");
  // Keyframe 0 of the message has 50 keypoints.
  EXPECT_EQ(r([](auto& m) { m.map_points()[3].obs_keypoint_index()[0] = 50; }),
            "server message: map point 3: observation 0: keypoint index 50 out of range");
  EXPECT_EQ(r([](auto& m) { m.map_points()[3].obs_kf_ids()[1] = Kf(1, 0); }),
            "server message: map point 3: observation 1: observing keyframe id 1:0 is invalid");
}

}  // namespace
}  // namespace ccm
