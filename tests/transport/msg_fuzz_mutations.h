// Mutations shared by the transport fuzz tests (msg_conversion_fuzz_test.cpp: agent messages
// into the server; agent_msg_fuzz_test.cpp: server messages into the agent, heartbeats into
// the server): field mutations of a ServerToAgent and byte-level ones on any serialized
// message (bit flips, truncation), deterministic for the MsgMutator's seed.
#pragma once

#include "idl/ccm_msgsPubSubTypes.h"
#include "tests/transport/msg_mutator.h"

namespace ccm::testing {

inline void MutateServer(MsgMutator& z, msg::ServerToAgent* m) {
  msg::ServerKeyframe* kf = m->keyframes().empty() ? nullptr : &m->keyframes()[z.Index(m->keyframes().size())];
  msg::ServerMapPoint* mp = m->map_points().empty() ? nullptr : &m->map_points()[z.Index(m->map_points().size())];
  msg::ServerKeyframePose* held =
      m->held_keyframes().empty() ? nullptr : &m->held_keyframes()[z.Index(m->held_keyframes().size())];
  switch (z.rng()() % 14) {
    case 0: m->protocol_version(z.Version()); break;
    case 1: m->agent_id(z.OtherAgent(m->agent_id())); break;
    case 2: m->ref_kf_id(z.Id(m->ref_kf_id())); break;
    case 3: if (!m->acked_kf_ids().empty()) m->acked_kf_ids()[0] = z.Id(m->acked_kf_ids()[0]); else z.Resize(&m->acked_mp_ids()); break;
    case 4: z.Chance(0.5) ? z.Resize(&m->keyframes()) : z.Resize(&m->map_points()); break;
    case 5: if (kf) kf->id(z.Id(kf->id())); break;
    case 6: if (kf) z.Pose(&kf->ref_from_this()); break;
    case 7: if (kf) { kf->pyramid_levels(z.Integer(kf->pyramid_levels())); kf->camera().fy(z.Chance(0.3) ? z.Realf(kf->camera().fy()) : kf->camera().fy()); } break;
    case 8: if (kf && !kf->keypoints().empty()) { auto& k = kf->keypoints()[z.Index(kf->keypoints().size())]; k.x_eighth_px(z.Integer(k.x_eighth_px())); k.octave(z.Chance(0.3) ? z.Integer(k.octave()) : k.octave()); } break;
    case 9: if (kf) z.Chance(0.5) ? z.Resize(&kf->keypoints()) : z.Resize(&kf->descriptors()); break;
    case 10: if (mp) { mp->z_ref(z.Realf(mp->z_ref())); if (!mp->obs_kf_ids().empty()) mp->obs_kf_ids()[0] = z.Id(mp->obs_kf_ids()[0]); } break;
    case 11: if (held) { z.Chance(0.5) ? held->id(z.Id(held->id())) : z.Pose(&held->ref_from_this()); } else z.Resize(&m->held_keyframes()); break;
    case 12: if (!m->held_map_points().empty()) { auto& h = m->held_map_points()[z.Index(m->held_map_points().size())]; z.Chance(0.5) ? h.id(z.Id(h.id())) : h.z_ref(z.Realf(h.z_ref())); } z.Resize(&m->held_map_points()); break;
    default: if (mp) { z.Chance(0.5) ? z.Resize(&mp->obs_kf_ids()) : z.Resize(&mp->obs_keypoint_index()); if (!mp->obs_keypoint_index().empty()) mp->obs_keypoint_index()[0] = z.Integer(mp->obs_keypoint_index()[0]); } break;
  }
}

// Byte-level: serialize, flip bits or cut the payload, deserialize. False when the
// deserializer refuses the bytes.
template <typename PubSubT>
bool MutateBytes(MsgMutator& z, typename PubSubT::type* m) {
  PubSubT type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(m)());
  if (!type.serialize(m, &payload)) return false;
  if (z.Chance(0.4)) {
    payload.length = static_cast<std::uint32_t>(z.Index(payload.length));  // truncated datagram
  } else {
    const int flips = 1 + static_cast<int>(z.Index(4));
    for (int i = 0; i < flips && payload.length > 4; ++i) {
      payload.data[4 + z.Index(payload.length - 4)] ^= static_cast<std::uint8_t>(1u << z.Index(8));  // body only
    }
  }
  typename PubSubT::type back;
  if (!type.deserialize(&payload, &back)) return false;
  *m = std::move(back);
  return true;
}

// 1-3 field mutations (85 %) or one byte-level mutation (15 %).
template <typename PubSubT, typename Fn>
bool Mutate(MsgMutator& z, typename PubSubT::type* m, Fn field_mutation) {
  if (z.Chance(0.15)) return MutateBytes<PubSubT>(z, m);
  const int n = 1 + static_cast<int>(z.Index(3));
  for (int i = 0; i < n; ++i) field_mutation(z, m);
  return true;
}

}  // namespace ccm::testing
