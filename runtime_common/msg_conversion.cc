// Agent -> server types: KeyframeFull, MapPointFull, KeyframeUpdate, MapPointUpdate.
#include "runtime_common/msg_conversion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "runtime_common/msg_conversion_util.h"

namespace ccm::conv {
namespace {

std::string Str(size_t v) { return std::to_string(v); }

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

// The keypoint-indexed links: equal lengths, indices inside the keyframe, valid point ids.
std::string LinksFromMsg(const msg::KeyframeFull& m, size_t num_keypoints, KeyframeData* kf) {
  const auto& index = m.mp_keypoint_index();
  const auto& ids = m.mp_ids();
  if (index.size() != ids.size()) return Str(index.size()) + " link indices but " + Str(ids.size()) + " link ids";
  if (index.size() > num_keypoints) return Str(index.size()) + " point links for " + Str(num_keypoints) + " keypoints";
  kf->point_links.reserve(index.size());
  for (size_t i = 0; i < index.size(); ++i) {
    if (index[i] >= num_keypoints) return "point link " + Str(i) + ": keypoint index " + Str(index[i]) + " out of range";
    MapPointId mp;
    if (auto e = AnyIdFromMsg(ids[i], "map point", true, &mp); !e.empty()) return "point link " + Str(i) + ": " + e;
    kf->point_links.emplace_back(index[i], mp);
  }
  return "";
}

// Everything of a KeyframeFull but its ids and the protocol version.
std::string KeyframeBodyFromMsg(const msg::KeyframeFull& m, CameraCache* cameras, KeyframeData* kf) {
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
  if (auto e = LinksFromMsg(m, kf->features->size(), kf); !e.empty()) return e;
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
  for (const auto& [index, mp] : kf.point_links) {
    if (index < 0 || static_cast<size_t>(index) >= sent) continue;  // left out with its keypoint
    m.mp_keypoint_index().push_back(static_cast<std::uint16_t>(index));
    m.mp_ids().push_back(mp.packed());
  }
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
  if (auto e = KeyframeBodyFromMsg(m, cameras, &kf); !e.empty()) return reject(e);
  kf.anchor_only = m.anchor_only();
  if (auto e = ValidateKeyframeData(kf, agent, kLimits); !e.empty()) return reject(e);
  if (agent_reference_kf != nullptr) *agent_reference_kf = reference;
  return kf;
}

msg::MapPointFull ToMsg(const MapPointData& mp) {
  msg::MapPointFull m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(mp.id.agent());
  m.id(mp.id.packed());
  m.segment_id(mp.segment.packed());
  m.ref_kf_id(mp.reference_kf.packed());
  m.x_ref(static_cast<float>(mp.position_ref.x()));
  m.y_ref(static_cast<float>(mp.position_ref.y()));
  m.z_ref(static_cast<float>(mp.position_ref.z()));
  for (const auto& [kf, index] : mp.observations) {
    if (m.obs_kf_ids().size() >= msg::kMaxObservations) break;
    if (index < 0 || index > std::numeric_limits<std::uint16_t>::max()) continue;
    m.obs_kf_ids().push_back(kf.packed());
    m.obs_keypoint_index().push_back(static_cast<std::uint16_t>(index));
  }
  return m;
}

std::optional<MapPointData> FromMsg(const msg::MapPointFull& m, std::string* error) {
  constexpr const char* kKind = "map point";
  auto reject = [&](const std::string& what) { return Reject<MapPointData>(error, kKind, what); };
  if (m.protocol_version() != msg::kProtocolVersion) return reject(VersionMismatch(m.protocol_version()));
  const AgentId agent = m.agent_id();
  MapPointData mp;
  if (auto e = OwnIdFromMsg(m.id(), agent, "map point", &mp.id); !e.empty()) return reject(e);
  if (auto e = OwnIdFromMsg(m.segment_id(), agent, "segment", &mp.segment); !e.empty()) return reject(e);
  if (auto e = OwnIdFromMsg(m.ref_kf_id(), agent, "reference keyframe", &mp.reference_kf); !e.empty()) return reject(e);
  if (auto e = PositionFromMsg(m.x_ref(), m.y_ref(), m.z_ref(), &mp.position_ref); !e.empty()) return reject(e);
  const auto& kfs = m.obs_kf_ids();
  const auto& index = m.obs_keypoint_index();
  if (kfs.size() != index.size()) return reject(Str(kfs.size()) + " observing keyframes but " + Str(index.size()) + " keypoint indices");
  if (kfs.size() > msg::kMaxObservations) return reject(Str(kfs.size()) + " observations (limit 64)");
  for (size_t i = 0; i < kfs.size(); ++i) {
    KeyframeId kf;
    if (auto e = OwnIdFromMsg(kfs[i], agent, "observing keyframe", &kf); !e.empty()) return reject("observation " + Str(i) + ": " + e);
    if (index[i] >= msg::kMaxKeypoints) return reject("observation " + Str(i) + ": keypoint index " + Str(index[i]) + " out of range");
    mp.observations.emplace_back(kf, index[i]);
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

msg::MapPointUpdate ToMsg(const MapPointPositionUpdate& u, MapId segment) {
  msg::MapPointUpdate m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(u.id.agent());
  m.segment_counter(SegmentCounter(segment, u.id.agent()));
  m.id(u.id.packed());
  m.ref_kf_id(u.reference_kf.packed());
  m.x_ref(static_cast<float>(u.position_ref.x()));
  m.y_ref(static_cast<float>(u.position_ref.y()));
  m.z_ref(static_cast<float>(u.position_ref.z()));
  return m;
}

std::optional<MapPointPositionUpdate> FromMsg(const msg::MapPointUpdate& m, std::string* error, MapId* segment) {
  constexpr const char* kKind = "map point update";
  auto reject = [&](const std::string& what) { return Reject<MapPointPositionUpdate>(error, kKind, what); };
  if (m.protocol_version() != msg::kProtocolVersion) return reject(VersionMismatch(m.protocol_version()));
  const AgentId agent = m.agent_id();
  MapPointPositionUpdate u;
  MapId seg;
  if (auto e = OwnIdFromMsg(m.id(), agent, "map point", &u.id); !e.empty()) return reject(e);
  if (auto e = SegmentFromCounter(m.segment_counter(), agent, &seg); !e.empty()) return reject(e);
  if (auto e = OwnIdFromMsg(m.ref_kf_id(), agent, "reference keyframe", &u.reference_kf); !e.empty()) return reject(e);
  if (auto e = PositionFromMsg(m.x_ref(), m.y_ref(), m.z_ref(), &u.position_ref); !e.empty()) return reject(e);
  if (auto e = ValidateMapPointPositionUpdate(u, agent, kLimits); !e.empty()) return reject(e);
  if (segment != nullptr) *segment = seg;
  return u;
}

}  // namespace ccm::conv
