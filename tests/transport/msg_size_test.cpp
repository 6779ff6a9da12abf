// Wire sizes of the protocol types against the CCM-SLAM budget (docs/architecture.md),
// and exact serialize/deserialize round trips.
#include <gtest/gtest.h>

#include <iostream>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/msg_conversion.h"
#include "runtime_common/synthetic_msgs.h"
#include "slam_core/common/ids.h"

namespace ccm {
namespace {

template <typename PubSubT>
std::uint32_t SerializedSize(typename PubSubT::type& msg, typename PubSubT::type* round_trip = nullptr) {
  PubSubT type;
  const std::uint32_t size = type.getSerializedSizeProvider(&msg)();
  eprosima::fastrtps::rtps::SerializedPayload_t payload(size);
  EXPECT_TRUE(type.serialize(&msg, &payload));
  EXPECT_EQ(payload.length, size);
  if (round_trip != nullptr) {
    EXPECT_TRUE(type.deserialize(&payload, round_trip));
  }
  return payload.length;
}

TEST(MsgSize, FullKeyframeAt1000FeaturesIsAbout40kB) {
  msg::KeyframeFull kf = synthetic::MakeKeyframe(3, 7, 1000, 300);
  msg::KeyframeFull back;
  const auto bytes = SerializedSize<msg::KeyframeFullPubSubType>(kf, &back);
  // 1000 x (6 B keypoint + 32 B descriptor) + 300 x 6 B links to own points + header/poses
  // (CCM-SLAM: 20 B per keypoint, ~55 kB).
  EXPECT_GE(bytes, 38000u);
  EXPECT_LE(bytes, 40500u);
  EXPECT_TRUE(back == kf);
  RecordProperty("keyframe_bytes", static_cast<int>(bytes));
  std::cout << "full keyframe, 1000 features, 300 links: " << bytes << " B\n";
}

TEST(MsgSize, KeypointCostsSixBytes) {
  msg::KeyframeFull a = synthetic::MakeKeyframe(1, 1, 100, 0);
  msg::KeyframeFull b = synthetic::MakeKeyframe(1, 1, 200, 0);
  const auto sa = SerializedSize<msg::KeyframeFullPubSubType>(a);
  const auto sb = SerializedSize<msg::KeyframeFullPubSubType>(b);
  EXPECT_EQ(sb - sa, 100u * (6u + 32u));  // keypoint + descriptor per feature
}

// A link to one of the agent's own points is a keypoint index and a 32-bit offset from the
// keyframe's base id; one to another agent's point carries the full 64-bit id.
TEST(MsgSize, OwnPointLinkCostsSixBytesOtherAgentsTen) {
  msg::KeyframeFull none = synthetic::MakeKeyframe(1, 1, 200, 0);
  msg::KeyframeFull own = synthetic::MakeKeyframe(1, 1, 200, 100);
  msg::KeyframeFull other = none;
  for (std::uint16_t i = 0; i < 100; ++i) {
    other.other_mp_keypoint_index().push_back(i);
    other.other_mp_ids().push_back(MapPointId::Make(2, 1000 + i).packed());
  }
  const auto s_none = SerializedSize<msg::KeyframeFullPubSubType>(none);
  EXPECT_EQ(SerializedSize<msg::KeyframeFullPubSubType>(own) - s_none, 100u * 6u);
  EXPECT_EQ(SerializedSize<msg::KeyframeFullPubSubType>(other) - s_none, 100u * 10u);
}

TEST(MsgSize, KeyframeUpdateFitsIn148Bytes) {
  msg::KeyframeUpdate u = synthetic::MakeKeyframeUpdate(2, 9);
  msg::KeyframeUpdate back;
  const auto bytes = SerializedSize<msg::KeyframeUpdatePubSubType>(u, &back);
  std::cout << "keyframe update: " << bytes << " B\n";
  EXPECT_LE(bytes, 148u);
  EXPECT_TRUE(back == u);
  EXPECT_LE(msg::KeyframeUpdatePubSubType().m_typeSize, 148u + 4u);  // bounded type, incl. padding
}

// CCM-SLAM's point update is 52 B; ours is 32 B in a batch (id, reference keyframe,
// position; version, agent and segment once per batch since version 8: 40 B before).
TEST(MsgSize, MapPointUpdateIs32BytesInABatch) {
  msg::MapPointUpdate u = synthetic::MakeMapPointUpdate(2, 9);
  msg::MapPointUpdate back;
  const auto bytes = SerializedSize<msg::MapPointUpdatePubSubType>(u, &back);
  std::cout << "map point update: " << bytes << " B (incl. the 4-byte encapsulation header)\n";
  EXPECT_EQ(bytes, 32u);
  EXPECT_TRUE(back == u);
  msg::MapPointUpdateBatch batch;
  batch.protocol_version(msg::kProtocolVersion);
  batch.agent_id(2);
  batch.segment_counter(1);
  const auto empty = SerializedSize<msg::MapPointUpdateBatchPubSubType>(batch);
  for (int i = 0; i < 30; ++i) batch.updates().push_back(synthetic::MakeMapPointUpdate(2, i));
  msg::MapPointUpdateBatch batch_back;
  const auto full = SerializedSize<msg::MapPointUpdateBatchPubSubType>(batch, &batch_back);
  EXPECT_EQ(full - empty, 30u * 32u);  // 8-byte aligned elements of 28 B
  EXPECT_TRUE(batch_back == batch);
}

TEST(MsgSize, FullMapPointAbout80BytesWithFiveObservations) {
  msg::MapPointFull mp = synthetic::MakeMapPoint(4, 11, 5);
  msg::MapPointFull back;
  const auto bytes = SerializedSize<msg::MapPointFullPubSubType>(mp, &back);
  std::cout << "full map point, 5 observations: " << bytes << " B\n";
  // ids 2 x 8, position 12, 5 x (4 + 2) observations + 2 x 4 sequence lengths (+ alignment);
  // no descriptor; version, agent and segment in the batch header. Version 7: 74-80 B
  // (version 4: 100 B, 64-bit segment and observing keyframe ids; 3: 132 B; 2: 152 B).
  EXPECT_GE(bytes, 66u);
  EXPECT_LE(bytes, 72u);
  EXPECT_TRUE(back == mp);
  // The common case, one observation: 42 B + the 4-byte encapsulation header here (in a
  // batch 48 B with the next point's alignment; version 7: 56, version 4: 64).
  msg::MapPointFull one = synthetic::MakeMapPoint(4, 11, 1);
  EXPECT_EQ(SerializedSize<msg::MapPointFullPubSubType>(one), 46u);
}

TEST(MsgSize, StatusAndServerMessagesRoundTrip) {
  msg::AgentStatus s = synthetic::MakeAgentStatus(5, 3), s_back;
  EXPECT_LE(SerializedSize<msg::AgentStatusPubSubType>(s, &s_back), 128u);
  EXPECT_TRUE(s_back == s);
  // k = 5 keyframes sent back per server message (CCM-SLAM), with their map points.
  msg::ServerToAgent m = synthetic::MakeServerToAgent(1, 5, 1000, 1500, 50), m_back;
  const auto bytes = SerializedSize<msg::ServerToAgentPubSubType>(m, &m_back);
  std::cout << "server message, 5 keyframes x 1000 features, 1500 points x 4 observations, 50 acks: " << bytes
            << " B\n";
  EXPECT_LE(bytes, 5u * 56000u + 1500u * 200u + 1000u);
  EXPECT_TRUE(m_back == m);
  // Per shared keyframe / point (differences, so the header cancels out).
  msg::ServerToAgent empty = synthetic::MakeServerToAgent(1, 0, 0, 0, 0);
  msg::ServerToAgent one_kf = synthetic::MakeServerToAgent(1, 1, 1000, 0, 0);
  msg::ServerToAgent one_mp = synthetic::MakeServerToAgent(1, 1, 0, 1, 0);
  msg::ServerToAgent one_kf_no_features = synthetic::MakeServerToAgent(1, 1, 0, 0, 0);
  const auto base = SerializedSize<msg::ServerToAgentPubSubType>(empty);
  const auto kf_bytes = SerializedSize<msg::ServerToAgentPubSubType>(one_kf) - base;
  const auto mp_bytes =
      SerializedSize<msg::ServerToAgentPubSubType>(one_mp) - SerializedSize<msg::ServerToAgentPubSubType>(one_kf_no_features);
  std::cout << "server keyframe, 1000 features: " << kf_bytes << " B; server map point, 4 observations: " << mp_bytes
            << " B\n";
  EXPECT_LE(kf_bytes, 56000u);
  // id 8 + position 12 + 4 x (8 B keyframe id + 2 B keypoint index) + 2 sequence lengths:
  // no descriptor since version 8 (104 B before).
  EXPECT_LE(mp_bytes, 72u);
}

TEST(MsgSize, EveryTopLevelTypeCarriesTheProtocolVersion) {
  EXPECT_EQ(synthetic::MakeKeyframe(1, 0, 10, 1).protocol_version(), msg::kProtocolVersion);
  EXPECT_EQ(conv::PointBatch(1, MapId::Make(1, 1)).protocol_version(), msg::kProtocolVersion);
  EXPECT_EQ(synthetic::MakeKeyframeUpdate(1, 0).protocol_version(), msg::kProtocolVersion);
  EXPECT_EQ(conv::PointUpdateBatch(1, MapId::Make(1, 1)).protocol_version(), msg::kProtocolVersion);
  EXPECT_EQ(synthetic::MakeAgentStatus(1, 0).protocol_version(), msg::kProtocolVersion);
  EXPECT_EQ(synthetic::MakeServerToAgent(1, 0, 0, 0, 0).protocol_version(), msg::kProtocolVersion);
}

}  // namespace
}  // namespace ccm
