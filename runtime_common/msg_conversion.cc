// Agent -> server types: KeyframeFull, MapPointBatch / MapPointFull, KeyframeUpdate,
// MapPointUpdateBatch / MapPointUpdate, AgentStatus.
#include "runtime_common/msg_conversion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "runtime_common/msg_conversion_util.h"

namespace ccm::conv {
namespace {

// 32-bit segment counter of the updates; 0 (rejected by receivers) if it does not fit.
std::uint32_t SegmentCounter(MapId segment, AgentId agent) {
  if (!segment.valid() || segment.agent() != agent || segment.counter() > std::numeric_limits<std::uint32_t>::max()) {
    return 0;
  }
  return static_cast<std::uint32_t>(segment.counter());
}

std::string SegmentFromCounter(std::uint32_t counter, AgentId agent, MapId* out) {
  if (counter == 0) return "segment counter is 0";
  *out = MapId::Make(agent, counter);
  return "";
}

template <typename Batch>
Batch BatchHeader(AgentId agent, MapId segment) {
  Batch b;
  b.protocol_version(msg::kProtocolVersion);
  b.agent_id(agent);
  b.segment_counter(SegmentCounter(segment, agent));
  return b;
}

std::optional<MapId> BatchSegment(const char* kind, unsigned version, AgentId agent, std::uint32_t counter,
                                  std::string* error) {
  if (version != msg::kProtocolVersion) return Reject<MapId>(error, kind, VersionMismatch(version));
  MapId segment;
  if (auto e = SegmentFromCounter(counter, agent, &segment); !e.empty()) return Reject<MapId>(error, kind, e);
  return segment;
}

// The keypoint-indexed links: equal lengths, indices inside the keyframe, valid point ids
// (own links: the base is the sender's own id and base + offset stays a valid counter).
std::string LinksFromMsg(const msg::KeyframeFull& m, AgentId agent, size_t num_keypoints, KeyframeData* kf) {
  const auto& own_index = m.own_mp_keypoint_index();
  const auto& offsets = m.own_mp_offsets();
  const auto& other_index = m.other_mp_keypoint_index();
  const auto& other_ids = m.other_mp_ids();
  if (own_index.size() != offsets.size()) {
    return Str(own_index.size()) + " own link indices but " + Str(offsets.size()) + " offsets";
  }
  if (other_index.size() != other_ids.size()) {
    return Str(other_index.size()) + " link indices but " + Str(other_ids.size()) + " link ids";
  }
  const size_t total = own_index.size() + other_index.size();
  if (total > num_keypoints) return Str(total) + " point links for " + Str(num_keypoints) + " keypoints";
  MapPointId base;
  if (!own_index.empty()) {
    if (auto e = OwnIdFromMsg(m.own_mp_base(), agent, "point link base", &base); !e.empty()) return e;
  }
  kf->point_links.reserve(total);
  for (size_t i = 0; i < own_index.size(); ++i) {
    if (own_index[i] >= num_keypoints) {
      return "own point link " + Str(i) + ": keypoint index " + Str(own_index[i]) + " out of range";
    }
    const std::uint64_t counter = base.counter() + offsets[i];
    if (counter > MapPointId::kCounterMask) return "own point link " + Str(i) + ": offset " + Str(offsets[i]) + " out of range";
    kf->point_links.emplace_back(own_index[i], MapPointId::Make(agent, counter));
  }
  for (size_t i = 0; i < other_index.size(); ++i) {
    if (other_index[i] >= num_keypoints) {
      return "point link " + Str(i) + ": keypoint index " + Str(other_index[i]) + " out of range";
    }
    MapPointId mp;
    if (auto e = AnyIdFromMsg(other_ids[i], "map point", true, &mp); !e.empty()) return "point link " + Str(i) + ": " + e;
    kf->point_links.emplace_back(other_index[i], mp);
  }
  // The links travel in two lists; the keyframe keeps them in keypoint order.
  std::sort(kf->point_links.begin(), kf->point_links.end());
  return "";
}

void LinksToMsg(const KeyframeData& kf, size_t sent_keypoints, msg::KeyframeFull* m) {
  const AgentId agent = kf.id.agent();
  MapPointId base;
  auto sent = [&](int index) { return index >= 0 && static_cast<size_t>(index) < sent_keypoints; };
  for (const auto& [index, mp] : kf.point_links) {
    if (sent(index) && mp.agent() == agent && (!base.valid() || mp.counter() < base.counter())) base = mp;
  }
  m->own_mp_base(base.packed());
  for (const auto& [index, mp] : kf.point_links) {
    if (!sent(index)) continue;  // left out with its keypoint
    const auto keypoint = static_cast<std::uint16_t>(index);
    if (mp.agent() == agent && mp.counter() - base.counter() <= std::numeric_limits<std::uint32_t>::max()) {
      m->own_mp_keypoint_index().push_back(keypoint);
      m->own_mp_offsets().push_back(static_cast<std::uint32_t>(mp.counter() - base.counter()));
    } else {
      m->other_mp_keypoint_index().push_back(keypoint);
      m->other_mp_ids().push_back(mp.packed());
    }
  }
}

// Everything of a KeyframeFull but its ids and the protocol version.
std::string KeyframeBodyFromMsg(const msg::KeyframeFull& m, AgentId agent, CameraCache* cameras, KeyframeData* kf) {
  if (m.stamp_ns() < 0) return "negative stamp";
  kf->stamp_ns = m.stamp_ns();
  if (auto e = CameraFromMsg(m.camera(), cameras, &kf->camera); !e.empty()) return e;
  kf->pyramid_levels = m.pyramid_levels();
  kf->pyramid_scale_factor = m.pyramid_scale_factor();
  if (auto e = CheckPyramid(kf->pyramid_levels, kf->pyramid_scale_factor); !e.empty()) return e;
  if (auto e = FeaturesFromMsg(m.keypoints(), m.descriptors(), *kf->camera, kf->pyramid_levels, &kf->features);
      !e.empty()) {
    return e;
  }
  if (auto e = LinksFromMsg(m, agent, kf->features->size(), kf); !e.empty()) return e;
  if (auto e = PoseFromMsg(m.pred_from_this(), "pred_from_this", &kf->pred_from_cam); !e.empty()) return e;
  if (auto e = PoseFromMsg(m.parent_from_this(), "parent_from_this", &kf->parent_from_cam); !e.empty()) return e;
  return PoseFromMsg(m.segment_from_this(), "segment_from_this", &kf->segment_from_cam);
}

}  // namespace

msg::KeyframeFull ToMsg(const KeyframeData& kf, KeyframeId agent_reference_kf) {
  msg::KeyframeFull m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(kf.id.agent());
  m.id(kf.id.packed());
  m.segment_id(kf.segment.packed());
  m.stamp_ns(kf.stamp_ns);
  if (kf.camera) m.camera(CameraToMsg(kf.camera->intrinsics()));
  m.pyramid_levels(static_cast<std::uint8_t>(std::clamp(kf.pyramid_levels, 0, 255)));
  m.pyramid_scale_factor(static_cast<float>(kf.pyramid_scale_factor));
  size_t sent = 0;
  if (kf.features) {
    sent = std::min<size_t>(kf.features->size(), msg::kMaxKeypoints);
    FeaturesToMsg(*kf.features, sent, &m.keypoints(), &m.descriptors());
  }
  LinksToMsg(kf, sent, &m);
  m.predecessor_id(kf.predecessor.packed());
  m.pred_from_this(PoseToMsg(kf.pred_from_cam));
  m.parent_id(kf.parent.packed());
  m.parent_from_this(PoseToMsg(kf.parent_from_cam));
  m.segment_from_this(PoseToMsg(kf.segment_from_cam));
  m.ref_kf_id(agent_reference_kf.packed());
  m.anchor_only(kf.anchor_only);
  return m;
}

std::optional<KeyframeData> FromMsg(const msg::KeyframeFull& m, CameraCache* cameras, std::string* error,
                                    KeyframeId* agent_reference_kf) {
  constexpr const char* kKind = "keyframe";
  auto reject = [&](const std::string& what) { return Reject<KeyframeData>(error, kKind, what); };
  if (m.protocol_version() != msg::kProtocolVersion) return reject(VersionMismatch(m.protocol_version()));
  const AgentId agent = m.agent_id();
  KeyframeData kf;
  KeyframeId reference;
  if (auto e = OwnIdFromMsg(m.id(), agent, "keyframe", &kf.id); !e.empty()) return reject(e);
  if (auto e = OwnIdFromMsg(m.segment_id(), agent, "segment", &kf.segment); !e.empty()) return reject(e);
  // Predecessor: the agent's own previous keyframe. Parent and reference keyframe may be
  // keyframes of other agents that the server shared.
  if (auto e = AnyIdFromMsg(m.predecessor_id(), "predecessor", false, &kf.predecessor); !e.empty()) return reject(e);
  if (kf.predecessor.valid() && kf.predecessor.agent() != agent) return reject("predecessor of another agent");
  if (auto e = AnyIdFromMsg(m.parent_id(), "parent", false, &kf.parent); !e.empty()) return reject(e);
  if (auto e = AnyIdFromMsg(m.ref_kf_id(), "reference keyframe", false, &reference); !e.empty()) return reject(e);
  if (auto e = KeyframeBodyFromMsg(m, agent, cameras, &kf); !e.empty()) return reject(e);
  kf.anchor_only = m.anchor_only();
  if (auto e = ValidateKeyframeData(kf, agent, kLimits); !e.empty()) return reject(e);
  if (agent_reference_kf != nullptr) *agent_reference_kf = reference;
  return kf;
}

msg::MapPointBatch PointBatch(AgentId agent, MapId segment) { return BatchHeader<msg::MapPointBatch>(agent, segment); }

msg::MapPointUpdateBatch PointUpdateBatch(AgentId agent, MapId segment) {
  return BatchHeader<msg::MapPointUpdateBatch>(agent, segment);
}

std::optional<MapId> BatchSegment(const msg::MapPointBatch& m, std::string* error) {
  return BatchSegment("map point batch", m.protocol_version(), m.agent_id(), m.segment_counter(), error);
}

std::optional<MapId> BatchSegment(const msg::MapPointUpdateBatch& m, std::string* error) {
  return BatchSegment("map point update batch", m.protocol_version(), m.agent_id(), m.segment_counter(), error);
}

msg::MapPointFull ToMsg(const MapPointData& mp) {
  msg::MapPointFull m;
  m.id(mp.id.packed());
  m.ref_kf_id(mp.reference_kf.packed());
  m.x_ref(static_cast<float>(mp.position_ref.x()));
  m.y_ref(static_cast<float>(mp.position_ref.y()));
  m.z_ref(static_cast<float>(mp.position_ref.z()));
  const auto ref = static_cast<std::int64_t>(mp.reference_kf.counter());
  for (const auto& [kf, index] : mp.observations) {
    if (m.obs_kf_offsets().size() >= msg::kMaxObservations) break;
    if (index < 0 || index > std::numeric_limits<std::uint16_t>::max()) continue;
    // Observers of one point are the agent's keyframes made close together. One more than
    // 2^31 keyframes away from the reference (never within one agent's life), or another
    // agent's (which receivers would reject), is left out like an out-of-range index.
    const std::int64_t offset = static_cast<std::int64_t>(kf.counter()) - ref;
    if (kf.agent() != mp.id.agent() || offset < std::numeric_limits<std::int32_t>::min() ||
        offset > std::numeric_limits<std::int32_t>::max()) {
      continue;
    }
    m.obs_kf_offsets().push_back(static_cast<std::int32_t>(offset));
    m.obs_keypoint_index().push_back(static_cast<std::uint16_t>(index));
  }
  return m;
}

std::optional<MapPointData> FromMsg(const msg::MapPointFull& m, AgentId agent, MapId segment, std::string* error) {
  constexpr const char* kKind = "map point";
  auto reject = [&](const std::string& what) { return Reject<MapPointData>(error, kKind, what); };
  MapPointData mp;
  mp.segment = segment;
  if (auto e = OwnIdFromMsg(m.id(), agent, "map point", &mp.id); !e.empty()) return reject(e);
  if (auto e = OwnIdFromMsg(m.ref_kf_id(), agent, "reference keyframe", &mp.reference_kf); !e.empty()) return reject(e);
  if (auto e = PositionFromMsg(m.x_ref(), m.y_ref(), m.z_ref(), &mp.position_ref); !e.empty()) return reject(e);
  const auto& offsets = m.obs_kf_offsets();
  const auto& index = m.obs_keypoint_index();
  if (offsets.size() != index.size()) {
    return reject(Str(offsets.size()) + " observing keyframes but " + Str(index.size()) + " keypoint indices");
  }
  if (offsets.size() > msg::kMaxObservations) return reject(Str(offsets.size()) + " observations (limit 64)");
  const auto ref = static_cast<std::int64_t>(mp.reference_kf.counter());
  for (size_t i = 0; i < offsets.size(); ++i) {
    const std::int64_t counter = ref + offsets[i];
    if (counter <= 0 || counter > static_cast<std::int64_t>(KeyframeId::kCounterMask)) {
      return reject("observation " + Str(i) + ": keyframe offset " + std::to_string(offsets[i]) + " out of range");
    }
    if (index[i] >= msg::kMaxKeypoints) return reject("observation " + Str(i) + ": keypoint index " + Str(index[i]) + " out of range");
    mp.observations.emplace_back(KeyframeId::Make(agent, static_cast<std::uint64_t>(counter)), index[i]);
  }
  // No descriptor on the wire: the server takes the point's from its observing keyframes
  // (Map::UpdateMapPointAppearance at registration), so mp.descriptor stays zero.
  if (auto e = ValidateMapPointData(mp, agent, kLimits); !e.empty()) return reject(e);
  return mp;
}

msg::KeyframeUpdate ToMsg(const KeyframePoseUpdate& u) {
  msg::KeyframeUpdate m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(u.id.agent());
  m.segment_counter(SegmentCounter(u.segment, u.id.agent()));
  m.id(u.id.packed());
  m.predecessor_id(u.predecessor.packed());
  m.parent_id(u.parent.packed());
  m.pred_from_this(PoseToMsg(u.pred_from_cam));
  m.parent_from_this(PoseToMsg(u.parent_from_cam));
  return m;
}

std::optional<KeyframePoseUpdate> FromMsg(const msg::KeyframeUpdate& m, std::string* error) {
  constexpr const char* kKind = "keyframe update";
  auto reject = [&](const std::string& what) { return Reject<KeyframePoseUpdate>(error, kKind, what); };
  if (m.protocol_version() != msg::kProtocolVersion) return reject(VersionMismatch(m.protocol_version()));
  const AgentId agent = m.agent_id();
  KeyframePoseUpdate u;
  if (auto e = OwnIdFromMsg(m.id(), agent, "keyframe", &u.id); !e.empty()) return reject(e);
  if (auto e = SegmentFromCounter(m.segment_counter(), agent, &u.segment); !e.empty()) return reject(e);
  if (auto e = AnyIdFromMsg(m.predecessor_id(), "predecessor", false, &u.predecessor); !e.empty()) return reject(e);
  if (u.predecessor.valid() && u.predecessor.agent() != agent) return reject("predecessor of another agent");
  if (auto e = AnyIdFromMsg(m.parent_id(), "parent", false, &u.parent); !e.empty()) return reject(e);
  if (auto e = PoseFromMsg(m.pred_from_this(), "pred_from_this", &u.pred_from_cam); !e.empty()) return reject(e);
  if (auto e = PoseFromMsg(m.parent_from_this(), "parent_from_this", &u.parent_from_cam); !e.empty()) return reject(e);
  if (auto e = ValidateKeyframePoseUpdate(u, agent, kLimits); !e.empty()) return reject(e);
  return u;
}

msg::MapPointUpdate ToMsg(const MapPointPositionUpdate& u) {
  msg::MapPointUpdate m;
  m.id(u.id.packed());
  m.ref_kf_id(u.reference_kf.packed());
  m.x_ref(static_cast<float>(u.position_ref.x()));
  m.y_ref(static_cast<float>(u.position_ref.y()));
  m.z_ref(static_cast<float>(u.position_ref.z()));
  return m;
}

std::optional<MapPointPositionUpdate> FromMsg(const msg::MapPointUpdate& m, AgentId agent, std::string* error) {
  constexpr const char* kKind = "map point update";
  auto reject = [&](const std::string& what) { return Reject<MapPointPositionUpdate>(error, kKind, what); };
  MapPointPositionUpdate u;
  if (auto e = OwnIdFromMsg(m.id(), agent, "map point", &u.id); !e.empty()) return reject(e);
  if (auto e = OwnIdFromMsg(m.ref_kf_id(), agent, "reference keyframe", &u.reference_kf); !e.empty()) return reject(e);
  if (auto e = PositionFromMsg(m.x_ref(), m.y_ref(), m.z_ref(), &u.position_ref); !e.empty()) return reject(e);
  if (auto e = ValidateMapPointPositionUpdate(u, agent, kLimits); !e.empty()) return reject(e);
  return u;
}

std::optional<AgentStatusData> FromMsg(const msg::AgentStatus& m, std::string* error) {
  constexpr const char* kKind = "status";
  auto reject = [&](const std::string& what) { return Reject<AgentStatusData>(error, kKind, what); };
  if (m.protocol_version() != msg::kProtocolVersion) return reject(VersionMismatch(m.protocol_version()));
  AgentStatusData st;
  st.agent = m.agent_id();
  if (st.agent == 0) return reject("agent id 0");
  if (m.ref_kf_id() != 0) {
    if (auto e = OwnIdFromMsg(m.ref_kf_id(), st.agent, "reference keyframe", &st.reference_kf); !e.empty()) return reject(e);
  }
  if (m.map_segment_id() != 0) {
    if (auto e = OwnIdFromMsg(m.map_segment_id(), st.agent, "segment", &st.segment); !e.empty()) return reject(e);
  }
  if (m.tracking_state() > 3) return reject("tracking state " + Str(m.tracking_state()) + " unknown");
  st.stamp_ns = m.stamp_ns();
  st.kfs_created = m.kfs_created();
  st.kfs_sent = m.kfs_sent();
  st.kfs_acked = m.kfs_acked();
  st.kfs_resent = m.kfs_resent();
  st.kfs_lost = m.kfs_lost();
  st.mps_sent = m.mps_sent();
  st.write_failures = m.write_failures();
  st.tracking_state = m.tracking_state();
  if (m.held_server_kf_ids().size() > msg::kMaxHeldKeyframes) return reject("too many held keyframes");
  st.holdings.applied_stamp_ns = m.server_data_stamp_ns();
  for (const auto packed : m.held_server_kf_ids()) {
    KeyframeId id;
    if (auto e = AnyIdFromMsg(packed, "held keyframe", true, &id); !e.empty()) return reject(e);
    st.holdings.keyframes.push_back(id);
  }
  return st;
}

}  // namespace ccm::conv
