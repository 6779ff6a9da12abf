// Server -> agent: ServerToAgent (acks and the server's map around the agent).
#include <algorithm>
#include <limits>
#include <unordered_map>
#include <unordered_set>

#include "runtime_common/msg_conversion.h"
#include "runtime_common/msg_conversion_util.h"

namespace ccm::conv {
namespace {

// ORB's pyramid. The ServerKeyframe value type carries none yet (the agent integrates server
// keyframes with its own pyramid); raised to cover the largest octave so the receiver's
// octave check holds.
constexpr int kDefaultPyramidLevels = 8;
constexpr float kDefaultPyramidScaleFactor = 1.2f;

// What the agent's FromMsg would reject (and with it the whole message): left out instead.
// A point the server's map holds at near-infinite depth (a degenerate triangulation) costed
// a 16-agent fleet run whole neighbourhoods ("position beyond 1e6 m").
bool Within(const Eigen::Vector3d& v) {
  return v.allFinite() && v.cwiseAbs().maxCoeff() <= kLimits.max_abs_coordinate_m;
}

bool SendablePose(const ServerKeyframe& kf) {
  return Within(kf.ref_from_cam.translation()) && kf.ref_from_cam.rotation().coeffs().allFinite();
}

bool Sendable(const ServerKeyframe& kf) {
  return kf.camera && kf.features && kf.features->size() <= msg::kMaxKeypoints &&
         kf.features->keypoints.size() == kf.features->descriptors.size() && SendablePose(kf);
}

bool Sendable(const ServerMapPoint& mp) { return Within(mp.position_ref); }

msg::ServerKeyframe KeyframeToMsg(const ServerKeyframe& kf) {
  msg::ServerKeyframe m;
  m.id(kf.id.packed());
  m.stamp_ns(kf.stamp_ns);
  m.camera(CameraToMsg(kf.camera->intrinsics()));
  FeaturesToMsg(*kf.features, kf.features->size(), &m.keypoints(), &m.descriptors());
  int levels = kDefaultPyramidLevels;
  for (const Keypoint& k : kf.features->keypoints) levels = std::max(levels, k.level + 1);
  m.pyramid_levels(static_cast<std::uint8_t>(std::clamp(levels, 0, 255)));
  m.pyramid_scale_factor(kDefaultPyramidScaleFactor);
  m.ref_from_this(PoseToMsg(kf.ref_from_cam));
  return m;
}

msg::ServerMapPoint PointToMsg(const ServerMapPoint& mp, const std::unordered_set<KeyframeId>& left_out) {
  msg::ServerMapPoint m;
  m.id(mp.id.packed());
  m.x_ref(static_cast<float>(mp.position_ref.x()));
  m.y_ref(static_cast<float>(mp.position_ref.y()));
  m.z_ref(static_cast<float>(mp.position_ref.z()));
  for (const auto& [kf, index] : mp.observations) {
    if (m.obs_kf_ids().size() >= msg::kMaxObservations) break;
    if (left_out.count(kf) || index < 0 || index >= static_cast<int>(msg::kMaxKeypoints)) continue;
    m.obs_kf_ids().push_back(kf.packed());
    m.obs_keypoint_index().push_back(static_cast<std::uint16_t>(index));
  }
  return m;
}

std::string KeyframeFromMsg(const msg::ServerKeyframe& m, CameraCache* cameras, ServerKeyframe* kf) {
  if (auto e = AnyIdFromMsg(m.id(), "keyframe", true, &kf->id); !e.empty()) return e;
  kf->stamp_ns = m.stamp_ns();
  if (auto e = CameraFromMsg(m.camera(), cameras, &kf->camera); !e.empty()) return e;
  if (auto e = CheckPyramid(m.pyramid_levels(), m.pyramid_scale_factor()); !e.empty()) return e;
  if (auto e = FeaturesFromMsg(m.keypoints(), m.descriptors(), *kf->camera, m.pyramid_levels(), &kf->features);
      !e.empty()) {
    return e;
  }
  return PoseFromMsg(m.ref_from_this(), "ref_from_this", &kf->ref_from_cam);
}

// `keypoints_of`: keypoint counts of the keyframes in the same message (observations of
// them must index a keypoint); others are the agent's own keyframes, checked on arrival.
std::string PointFromMsg(const msg::ServerMapPoint& m, const std::unordered_map<KeyframeId, size_t>& keypoints_of,
                         ServerMapPoint* mp) {
  if (auto e = AnyIdFromMsg(m.id(), "map point", true, &mp->id); !e.empty()) return e;
  if (auto e = PositionFromMsg(m.x_ref(), m.y_ref(), m.z_ref(), &mp->position_ref); !e.empty()) return e;
  const auto& kfs = m.obs_kf_ids();
  const auto& index = m.obs_keypoint_index();
  if (kfs.size() != index.size()) return Str(kfs.size()) + " observing keyframes but " + Str(index.size()) + " keypoint indices";
  if (kfs.size() > msg::kMaxObservations) return Str(kfs.size()) + " observations (limit 64)";
  for (size_t i = 0; i < kfs.size(); ++i) {
    KeyframeId kf;
    if (auto e = AnyIdFromMsg(kfs[i], "observing keyframe", true, &kf); !e.empty()) return "observation " + Str(i) + ": " + e;
    const auto it = keypoints_of.find(kf);
    const size_t limit = it != keypoints_of.end() ? it->second : msg::kMaxKeypoints;
    if (index[i] >= limit) return "observation " + Str(i) + ": keypoint index " + Str(index[i]) + " out of range";
    mp->observations.emplace_back(kf, index[i]);
  }
  return "";
}

std::string AcksFromMsg(const msg::ServerToAgent& m, AgentId agent, ServerMessage* out) {
  if (m.acked_kf_ids().size() > msg::kMaxAcks || m.acked_mp_ids().size() > msg::kMaxAcks) return "too many acks";
  for (const auto packed : m.acked_kf_ids()) {
    KeyframeId id;
    if (auto e = OwnIdFromMsg(packed, agent, "acked keyframe", &id); !e.empty()) return e;
    out->acked_kfs.push_back(id);
  }
  for (const auto packed : m.acked_mp_ids()) {
    MapPointId id;
    if (auto e = OwnIdFromMsg(packed, agent, "acked map point", &id); !e.empty()) return e;
    out->acked_mps.push_back(id);
  }
  return "";
}

std::string MapDataFromMsg(const msg::ServerToAgent& m, CameraCache* cameras, ServerMapData* data) {
  if (m.keyframes().size() > msg::kMaxKeyframesPerServerMsg) return Str(m.keyframes().size()) + " keyframes (limit 16)";
  if (m.map_points().size() > msg::kMaxMapPointsPerServerMsg) return Str(m.map_points().size()) + " map points (limit 4096)";
  // The reference may be another agent's keyframe the agent tracks against.
  if (auto e = AnyIdFromMsg(m.ref_kf_id(), "reference keyframe", true, &data->reference_kf); !e.empty()) return e;
  if (m.held_keyframes().size() > msg::kMaxKeyframesPerServerMsg) {
    return Str(m.held_keyframes().size()) + " held keyframes (limit 16)";
  }
  data->stamp_ns = m.stamp_ns();
  std::unordered_map<KeyframeId, size_t> keypoints_of;
  data->keyframes.resize(m.keyframes().size());
  for (size_t i = 0; i < m.keyframes().size(); ++i) {
    ServerKeyframe& kf = data->keyframes[i];
    if (auto e = KeyframeFromMsg(m.keyframes()[i], cameras, &kf); !e.empty()) return "keyframe " + Str(i) + ": " + e;
    if (!keypoints_of.emplace(kf.id, kf.features->size()).second) return "keyframe " + Str(i) + ": id sent twice";
  }
  // Held keyframes: the agent checks their points' keypoint indices on arrival, as for its own.
  std::unordered_set<KeyframeId> held;
  for (size_t i = 0; i < m.held_keyframes().size(); ++i) {
    ServerKeyframe kf;
    kf.held = true;
    const auto& h = m.held_keyframes()[i];
    if (auto e = AnyIdFromMsg(h.id(), "held keyframe", true, &kf.id); !e.empty()) return "held keyframe " + Str(i) + ": " + e;
    if (auto e = PoseFromMsg(h.ref_from_this(), "ref_from_this", &kf.ref_from_cam); !e.empty()) {
      return "held keyframe " + Str(i) + ": " + e;
    }
    if (keypoints_of.count(kf.id) || !held.insert(kf.id).second) return "held keyframe " + Str(i) + ": id sent twice";
    data->keyframes.push_back(std::move(kf));
  }
  std::unordered_set<MapPointId> seen;
  data->map_points.resize(m.map_points().size());
  for (size_t i = 0; i < m.map_points().size(); ++i) {
    ServerMapPoint& mp = data->map_points[i];
    if (auto e = PointFromMsg(m.map_points()[i], keypoints_of, &mp); !e.empty()) return "map point " + Str(i) + ": " + e;
    if (!seen.insert(mp.id).second) return "map point " + Str(i) + ": id sent twice";
  }
  if (m.held_map_points().size() > msg::kMaxMapPointsPerServerMsg) {
    return Str(m.held_map_points().size()) + " held map points (limit 4096)";
  }
  for (size_t i = 0; i < m.held_map_points().size(); ++i) {
    const auto& h = m.held_map_points()[i];
    ServerMapPoint mp;
    mp.held = true;
    if (auto e = AnyIdFromMsg(h.id(), "held map point", true, &mp.id); !e.empty()) return "held map point " + Str(i) + ": " + e;
    if (auto e = PositionFromMsg(h.x_ref(), h.y_ref(), h.z_ref(), &mp.position_ref); !e.empty()) {
      return "held map point " + Str(i) + ": " + e;
    }
    if (!seen.insert(mp.id).second) return "held map point " + Str(i) + ": id sent twice";
    data->map_points.push_back(std::move(mp));
  }
  return "";
}

}  // namespace

msg::ServerToAgent ToMsg(AgentId agent, int64_t stamp_ns, const std::vector<KeyframeId>& acked_kfs,
                         const std::vector<MapPointId>& acked_mps, const ServerMapData* data,
                         const ServerAckStamp& ack_stamp) {
  msg::ServerToAgent m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(agent);
  m.stamp_ns(stamp_ns);
  m.server_epoch(ack_stamp.epoch);
  m.ack_seq(ack_stamp.ack_seq);
  m.persisted_seq(ack_stamp.persisted_seq);
  for (size_t i = 0; i < acked_kfs.size() && i < msg::kMaxAcks; ++i) m.acked_kf_ids().push_back(acked_kfs[i].packed());
  for (size_t i = 0; i < acked_mps.size() && i < msg::kMaxAcks; ++i) m.acked_mp_ids().push_back(acked_mps[i].packed());
  if (data == nullptr) return m;
  m.ref_kf_id(data->reference_kf.packed());
  std::unordered_set<KeyframeId> left_out;
  for (const ServerKeyframe& kf : data->keyframes) {
    if (kf.held) {
      if (m.held_keyframes().size() >= msg::kMaxKeyframesPerServerMsg || !SendablePose(kf)) {
        left_out.insert(kf.id);
        continue;
      }
      msg::ServerKeyframePose h;
      h.id(kf.id.packed());
      h.ref_from_this(PoseToMsg(kf.ref_from_cam));
      m.held_keyframes().push_back(h);
      continue;
    }
    if (m.keyframes().size() >= msg::kMaxKeyframesPerServerMsg || !Sendable(kf)) {
      left_out.insert(kf.id);
      continue;
    }
    m.keyframes().push_back(KeyframeToMsg(kf));
  }
  for (const ServerMapPoint& mp : data->map_points) {
    if (!Sendable(mp)) continue;
    if (mp.held) {
      // The agent keeps its own estimate of its own points (ServerDataIntegrator): the
      // position of one it holds would be ignored. ~20 B each, thousands per minute.
      if (mp.id.agent() == agent || m.held_map_points().size() >= msg::kMaxMapPointsPerServerMsg) continue;
      msg::ServerMapPointPosition h;
      h.id(mp.id.packed());
      h.x_ref(static_cast<float>(mp.position_ref.x()));
      h.y_ref(static_cast<float>(mp.position_ref.y()));
      h.z_ref(static_cast<float>(mp.position_ref.z()));
      m.held_map_points().push_back(h);
    } else if (m.map_points().size() < msg::kMaxMapPointsPerServerMsg) {
      m.map_points().push_back(PointToMsg(mp, left_out));
    }
  }
  return m;
}

std::optional<ServerMessage> FromMsg(const msg::ServerToAgent& m, AgentId expected_agent, CameraCache* cameras,
                                     std::string* error) {
  constexpr const char* kKind = "server message";
  auto reject = [&](const std::string& what) { return Reject<ServerMessage>(error, kKind, what); };
  if (m.protocol_version() != msg::kProtocolVersion) return reject(VersionMismatch(m.protocol_version()));
  if (m.agent_id() != expected_agent) {
    return reject("addressed to agent " + std::to_string(m.agent_id()) + ", not " + std::to_string(expected_agent));
  }
  if (m.server_epoch() == 0) return reject("server epoch 0");
  ServerMessage out;
  out.stamp_ns = m.stamp_ns();
  out.ack_stamp = {m.server_epoch(), m.ack_seq(), m.persisted_seq()};
  if (auto e = AcksFromMsg(m, expected_agent, &out); !e.empty()) return reject(e);
  if (m.keyframes().empty() && m.map_points().empty() && m.held_keyframes().empty() && m.held_map_points().empty()) {
    return out;
  }
  ServerMapData data;
  if (auto e = MapDataFromMsg(m, cameras, &data); !e.empty()) return reject(e);
  out.data = std::move(data);
  return out;
}

}  // namespace ccm::conv
