// Fuzz tests of what the agent receives and what the server learns from heartbeats:
//  * AgentStatus: mutated heartbeats through conv::FromMsg (what ServerComm does with each):
//    every one is refused with a message or accepted with exactly the message's fields, its
//    ids the sender's own (or none), a known tracking state.
//  * ServerToAgent into the agent: mutated server messages (neighbourhoods of keyframes and
//    points of "agent 2", built from the agent's own flight, and synthetic ones) through
//    conv::FromMsg and, when accepted, into a tracking AgentVo's ApplyServerData, as
//    AgentComm::HandleServerMessage does; the VO keeps tracking between them. No crash, every
//    message accounted for, and the local map stays consistent (observations inside their
//    keyframes, finite poses and positions).
// Inputs: CCM_FUZZ_INPUTS (3,000 in the normal run; 100,000 in deploy/run-sanitizer-tests.sh).
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/msg_conversion.h"
#include "tests/fuzz_inputs.h"
#include "tests/slam_core/server/server_test_util.h"
#include "tests/transport/conversion_test_data.h"
#include "tests/transport/msg_fuzz_mutations.h"

namespace ccm {
namespace {

using testing::MsgMutator;

constexpr AgentId kFuzzedAgent = 1;

void MutateStatus(MsgMutator& z, msg::AgentStatus* m) {
  switch (z.rng()() % 9) {
    case 0: m->protocol_version(z.Version()); break;
    case 7: z.Chance(0.5) ? z.Resize(&m->held_server_kf_ids()) : m->server_data_stamp_ns(z.Integer(m->server_data_stamp_ns()));
      if (!m->held_server_kf_ids().empty()) m->held_server_kf_ids()[0] = z.Id(m->held_server_kf_ids()[0]);
      break;
    case 1: m->agent_id(z.Chance(0.3) ? 0 : z.OtherAgent(m->agent_id())); break;
    case 2: m->ref_kf_id(z.Id(m->ref_kf_id())); break;
    case 3: m->map_segment_id(z.Id(m->map_segment_id())); break;
    case 4: m->tracking_state(z.Integer(m->tracking_state())); break;
    case 5: m->stamp_ns(z.Integer(m->stamp_ns())); break;
    case 6: m->kfs_acked(z.Integer(m->kfs_acked())); m->kfs_lost(z.Integer(m->kfs_lost())); break;
    default: m->kfs_sent(z.Integer(m->kfs_sent())); m->write_failures(z.Integer(m->write_failures())); break;
  }
}

// Why an accepted heartbeat is not what the message said or breaks a rule, or "".
std::string StatusViolation(const msg::AgentStatus& m, const conv::AgentStatusData& st) {
  if (m.protocol_version() != msg::kProtocolVersion) return "another protocol version";
  if (st.agent == 0 || st.agent != m.agent_id()) return "agent id";
  if (st.reference_kf.packed() != m.ref_kf_id() || st.segment.packed() != m.map_segment_id()) return "ids changed";
  if (m.ref_kf_id() != 0 && (!st.reference_kf.valid() || st.reference_kf.agent() != st.agent)) return "reference";
  if (m.map_segment_id() != 0 && (!st.segment.valid() || st.segment.agent() != st.agent)) return "segment";
  if (st.tracking_state < 0 || st.tracking_state > 3 || st.tracking_state != m.tracking_state()) return "tracking state";
  if (st.kfs_acked != m.kfs_acked() || st.kfs_sent != m.kfs_sent() || st.kfs_lost != m.kfs_lost() ||
      st.write_failures != m.write_failures() || st.stamp_ns != m.stamp_ns()) {
    return "counters changed";
  }
  if (st.holdings.applied_stamp_ns != m.server_data_stamp_ns() ||
      st.holdings.keyframes.size() != m.held_server_kf_ids().size()) {
    return "holdings changed";
  }
  for (size_t i = 0; i < st.holdings.keyframes.size(); ++i) {
    if (!st.holdings.keyframes[i].valid() || st.holdings.keyframes[i].packed() != m.held_server_kf_ids()[i]) return "held id";
  }
  return "";
}

TEST(AgentStatusFuzz, MutatedHeartbeatsAreRefusedWithAMessageOrAcceptedAsSent) {
  msg::AgentStatus base;
  base.protocol_version(msg::kProtocolVersion);
  base.agent_id(kFuzzedAgent);
  base.stamp_ns(1'700'000'000'000'000'000);
  base.ref_kf_id(KeyframeId::Make(kFuzzedAgent, 40).packed());
  base.map_segment_id(MapId::Make(kFuzzedAgent, 1).packed());
  base.kfs_created(45), base.kfs_sent(44), base.kfs_acked(40), base.kfs_resent(2), base.mps_sent(3000);
  base.tracking_state(1);
  base.server_data_stamp_ns(1'700'000'000'000'000'000);
  base.held_server_kf_ids().push_back(KeyframeId::Make(2, 17).packed());
  base.held_server_kf_ids().push_back(KeyframeId::Make(3, 4).packed());
  std::string error;
  ASSERT_TRUE(conv::FromMsg(base, &error)) << error;

  const int total = testing::FuzzInputs(5000);
  MsgMutator z(20261128);
  int accepted = 0, refused = 0, silent = 0, invalid = 0;
  std::map<std::string, int> reasons;
  for (int i = 0; i < total; ++i) {
    msg::AgentStatus m = base;
    if (!testing::Mutate<msg::AgentStatusPubSubType>(z, &m, MutateStatus)) {
      ++refused;  // the deserializer refused the bytes
      ++reasons["payload refused by the deserializer"];
      continue;
    }
    error.clear();
    const auto st = conv::FromMsg(m, &error);
    if (!st) {
      ++refused;
      silent += error.empty();
      ++reasons[conv::ReasonKind(error)];
      continue;
    }
    ++accepted;
    const std::string v = StatusViolation(m, *st);
    EXPECT_EQ(v, "") << "accepted heartbeat " << i;
    invalid += !v.empty();
  }
  std::cout << total << " heartbeats: " << accepted << " accepted, " << refused << " refused (" << reasons.size()
            << " kinds)\n";
  for (const auto& [reason, count] : reasons) std::cout << "  " << count << "  " << reason << "\n";
  EXPECT_EQ(silent, 0);
  EXPECT_EQ(invalid, 0);
  EXPECT_GT(accepted, total / 10);
  EXPECT_GT(refused, total / 10);
}

// The local map's own rules after hostile server data: what tracking and local BA index.
std::string MapViolation(const Map& map) {
  for (const auto& kf : map.keyframes()) {
    if (!kf->world_from_cam().translation().allFinite() || !kf->world_from_cam().rotation().coeffs().allFinite()) {
      return "keyframe pose not finite";
    }
    if (kf->map_points().size() != kf->num_keypoints()) return "keyframe point slots";
  }
  for (const auto& mp : map.map_points()) {
    if (!mp->position().allFinite()) return "point position not finite";
    for (const auto& [kf_id, index] : mp->observations()) {
      const auto kf = map.keyframe(kf_id);
      if (!kf) return "observation by a keyframe not in the map";
      if (index < 0 || static_cast<size_t>(index) >= kf->num_keypoints()) return "observation index outside its keyframe";
    }
  }
  return "";
}

TEST(ServerMessageFuzz, MutatedServerMessagesIntoATrackingAgentNeverBreakItsMap) {
  const auto sim = testing::LoadSim("hall3");
  ASSERT_TRUE(sim);
  sim::SimFrameSource source(sim, 0, 0, 1, 400);
  std::shared_ptr<const CameraModel> camera(MakeCamera(source.intrinsics()));
  AckAll acks;
  AgentVo vo(kFuzzedAgent, camera, VoOptions{}, &acks, /*synchronous_mapping=*/true);
  for (int i = 0; i < 60; ++i) vo.TrackFrame(*source.Next());
  const VoChanges changes = vo.TakeChanges();
  ASSERT_TRUE(changes.map && changes.reference_kf.valid());
  const auto ref = changes.map->keyframe(changes.reference_kf);
  ASSERT_NE(ref, nullptr);

  // Base: the agent's older keyframes and their points as "agent 2's", where the server
  // would put them (the reference keyframe's frame), with acks; and a synthetic neighbourhood.
  ServerMapData data;
  data.reference_kf = ref->id();
  std::map<MapPointId, ServerMapPoint> points;
  int copied = 0;
  for (const auto& kf : changes.map->keyframes()) {
    if (kf->id() == ref->id() || copied == 4) continue;
    const KeyframeId foreign = KeyframeId::Make(2, 1000 + copied++);
    data.keyframes.push_back({foreign, kf->stamp_ns(), kf->camera_ptr(), kf->features_ptr(),
                              ref->cam_from_world() * kf->world_from_cam()});
    const auto mps = kf->map_points();
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
  ASSERT_GT(copied, 1);
  std::vector<msg::ServerToAgent> base{conv::ToMsg(kFuzzedAgent, 1, {ref->id()}, {}, &data),
                                       conv::ToMsg(kFuzzedAgent, 2, {ref->id()}, {}, nullptr)};
  const ServerMapData synthetic = testing::MakeServerMapData(kFuzzedAgent, 5, 500, 300);
  base.push_back(conv::ToMsg(kFuzzedAgent, 3, {KeyframeId::Make(kFuzzedAgent, 1)}, {}, &synthetic));
  // Downlink deltas: the same neighbourhood with two keyframes and half the points the agent
  // holds, as poses and positions only.
  ServerMapData delta = data;
  delta.keyframes[0].held = delta.keyframes[1].held = true;
  for (size_t i = 0; i < delta.map_points.size(); i += 2) delta.map_points[i].held = true;
  base.push_back(conv::ToMsg(kFuzzedAgent, 4, {}, {}, &delta));
  ASSERT_EQ(base.back().held_keyframes().size(), 2u);
  ASSERT_FALSE(base.back().held_map_points().empty());
  conv::CameraCache cameras(8);
  std::string error;
  for (const auto& m : base) ASSERT_TRUE(conv::FromMsg(m, kFuzzedAgent, &cameras, &error)) << error;

  const int total = testing::FuzzInputs(3000);
  MsgMutator z(20261129);
  int accepted = 0, applied = 0, refused = 0, silent = 0, frames = 0, tracked = 0;
  std::map<std::string, int> reasons;
  for (int i = 0; i < total; ++i) {
    msg::ServerToAgent m = base[z.Index(base.size())];
    error.clear();
    std::optional<conv::ServerMessage> got;
    if (testing::Mutate<msg::ServerToAgentPubSubType>(z, &m, testing::MutateServer)) {
      got = conv::FromMsg(m, kFuzzedAgent, &cameras, &error);
      silent += !got && error.empty();
    }
    if (!got) {
      ++refused;
      ++reasons[error.empty() ? "payload refused by the deserializer" : conv::ReasonKind(error)];
    } else {
      ++accepted;
      if (got->data) {
        vo.ApplyServerData(std::move(*got->data));
        vo.DrainMapping();
        ++applied;
      }
    }
    // The agent keeps flying: one frame every total / 40 messages.
    if (i % std::max(1, total / 40) == 0) {
      if (auto f = source.Next()) {
        ++frames;
        tracked += vo.TrackFrame(*f).world_from_cam.has_value();
      }
    }
    if (i % 500 == 499) {
      ASSERT_EQ(MapViolation(*vo.map()), "") << "after message " << i;
    }
  }
  vo.DrainMapping();
  EXPECT_EQ(MapViolation(*vo.map()), "");
  const AgentVoStats s = vo.stats();
  std::cout << total << " server messages: " << accepted << " accepted (" << applied << " with data applied), "
            << refused << " refused (" << reasons.size() << " kinds); " << s.server.keyframes_added
            << " server keyframes and " << s.server.points_added << " points integrated; " << tracked << "/" << frames
            << " frames tracked meanwhile\n";
  EXPECT_EQ(silent, 0);
  EXPECT_EQ(accepted + refused, total);
  EXPECT_GT(applied, total / 20);
  EXPECT_GT(refused, total / 10);
  EXPECT_GT(s.server.keyframes_added, 0);
}

}  // namespace
}  // namespace ccm
