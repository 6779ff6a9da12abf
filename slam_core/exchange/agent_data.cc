#include "slam_core/exchange/agent_data.h"

#include <cmath>

namespace ccm {
namespace {

std::string Str(size_t v) { return std::to_string(v); }

bool FinitePose(const SE3& T, double max_abs) {
  const Eigen::Quaterniond& q = T.rotation();
  return T.translation().allFinite() && T.translation().cwiseAbs().maxCoeff() <= max_abs && q.coeffs().allFinite() &&
         std::abs(q.norm() - 1.0) < 1e-6;
}

template <typename IdT>
std::string CheckOwnId(IdT id, AgentId agent, const char* what) {
  if (!id.valid()) return std::string(what) + " id is invalid";
  if (id.agent() != agent) {
    return std::string(what) + " id belongs to agent " + std::to_string(id.agent()) + ", not to sender " +
           std::to_string(agent);
  }
  return "";
}

std::string CheckFeatures(const KeyframeData& kf, const AgentDataLimits& limits) {
  if (!kf.features) return "no features";
  const FrameFeatures& f = *kf.features;
  if (f.keypoints.size() != f.descriptors.size()) {
    return Str(f.keypoints.size()) + " keypoints but " + Str(f.descriptors.size()) + " descriptors";
  }
  if (f.keypoints.size() > limits.max_keypoints) return Str(f.keypoints.size()) + " keypoints (limit " + Str(limits.max_keypoints) + ")";
  const double w = kf.camera->width(), h = kf.camera->height();
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    const Keypoint& k = f.keypoints[i];
    if (!std::isfinite(k.u) || !std::isfinite(k.v) || k.u < -1 || k.v < -1 || k.u > w || k.v > h) {
      return "keypoint " + Str(i) + " outside the image";
    }
    if (k.level < 0 || k.level >= kf.pyramid_levels) return "keypoint " + Str(i) + ": octave out of range";
    if (!std::isfinite(k.angle_deg) || !std::isfinite(k.response)) return "keypoint " + Str(i) + ": non-finite value";
  }
  return "";
}

}  // namespace

std::string ValidateKeyframeData(const KeyframeData& kf, AgentId agent, const AgentDataLimits& limits) {
  if (auto e = CheckOwnId(kf.id, agent, "keyframe"); !e.empty()) return e;
  if (auto e = CheckOwnId(kf.segment, agent, "segment"); !e.empty()) return e;
  if (!kf.camera) return "keyframe " + Str(kf.id.counter()) + ": no camera";
  if (const std::string e = ValidateIntrinsics(kf.camera->intrinsics()); !e.empty()) return "camera: " + e;
  if (kf.pyramid_levels < 1 || kf.pyramid_levels > 16) return "pyramid levels must be in 1..16";
  if (!(kf.pyramid_scale_factor > 1.0 && kf.pyramid_scale_factor <= 2.0)) return "pyramid scale factor must be in (1, 2]";
  if (auto e = CheckFeatures(kf, limits); !e.empty()) return "keyframe " + Str(kf.id.counter()) + ": " + e;
  if (kf.anchor_only) {
    if (kf.features->size() != 0 || !kf.point_links.empty()) return "anchor-only keyframe with features or point links";
    if (!kf.parent.valid()) return "anchor-only keyframe without the keyframe it duplicates (parent)";
  }
  const size_t n = kf.features->size();
  std::vector<bool> used(n, false);
  for (size_t i = 0; i < kf.point_links.size(); ++i) {
    const auto& [idx, mp] = kf.point_links[i];
    if (idx < 0 || static_cast<size_t>(idx) >= n) return "point link " + Str(i) + ": keypoint index out of range";
    if (used[idx]) return "point link " + Str(i) + ": keypoint linked twice";
    used[idx] = true;
    // Links may name other agents' points: the agent tracked points the server shared.
    if (!mp.valid()) return "point link " + Str(i) + ": invalid map point id";
  }
  if (kf.predecessor.valid() && (kf.predecessor.agent() != agent || kf.predecessor == kf.id)) return "bad predecessor id";
  // The parent may be another agent's keyframe the server shared (the server has it).
  if (kf.parent == kf.id) return "bad parent id";
  for (const SE3* T : {&kf.pred_from_cam, &kf.parent_from_cam, &kf.segment_from_cam}) {
    if (!FinitePose(*T, limits.max_abs_coordinate_m)) return "keyframe " + Str(kf.id.counter()) + ": invalid pose";
  }
  return "";
}

std::string ValidateMapPointData(const MapPointData& mp, AgentId agent, const AgentDataLimits& limits) {
  if (auto e = CheckOwnId(mp.id, agent, "map point"); !e.empty()) return e;
  if (auto e = CheckOwnId(mp.segment, agent, "segment"); !e.empty()) return e;
  if (auto e = CheckOwnId(mp.reference_kf, agent, "reference keyframe"); !e.empty()) return e;
  if (!mp.position_ref.allFinite() || mp.position_ref.cwiseAbs().maxCoeff() > limits.max_abs_coordinate_m) {
    return "map point " + Str(mp.id.counter()) + ": invalid position";
  }
  if (mp.observations.size() > limits.max_observations) return "map point: too many observations";
  for (const auto& [kf, idx] : mp.observations) {
    if (auto e = CheckOwnId(kf, agent, "observing keyframe"); !e.empty()) return e;
    if (idx < 0 || static_cast<size_t>(idx) >= limits.max_keypoints) return "map point: keypoint index out of range";
  }
  return "";
}

std::string ValidateKeyframePoseUpdate(const KeyframePoseUpdate& u, AgentId agent, const AgentDataLimits& limits) {
  if (auto e = CheckOwnId(u.id, agent, "updated keyframe"); !e.empty()) return e;
  if (u.predecessor.valid() && u.predecessor.agent() != agent) return "bad predecessor id";
  if (!FinitePose(u.pred_from_cam, limits.max_abs_coordinate_m) || !FinitePose(u.parent_from_cam, limits.max_abs_coordinate_m)) {
    return "keyframe update: invalid pose";
  }
  return "";
}

std::string ValidateMapPointPositionUpdate(const MapPointPositionUpdate& u, AgentId agent,
                                           const AgentDataLimits& limits) {
  if (auto e = CheckOwnId(u.id, agent, "updated map point"); !e.empty()) return e;
  if (auto e = CheckOwnId(u.reference_kf, agent, "reference keyframe"); !e.empty()) return e;
  if (!u.position_ref.allFinite() || u.position_ref.cwiseAbs().maxCoeff() > limits.max_abs_coordinate_m) {
    return "map point update: invalid position";
  }
  return "";
}

size_t ApproxBatchBytes(const AgentBatch& batch) {
  size_t bytes = sizeof(AgentBatch);
  for (const KeyframeData& k : batch.keyframes) {
    bytes += sizeof(KeyframeData) + k.point_links.size() * sizeof(k.point_links[0]);
    // Features are shared (a resend may point at the same ones); counted anyway, as a
    // hostile agent's would not be shared.
    if (k.features) bytes += k.features->keypoints.size() * (sizeof(Keypoint) + sizeof(OrbDescriptor));
  }
  for (const MapPointData& m : batch.map_points) {
    bytes += sizeof(MapPointData) + m.observations.size() * sizeof(m.observations[0]);
  }
  bytes += batch.keyframe_updates.size() * sizeof(KeyframePoseUpdate);
  bytes += batch.map_point_updates.size() * sizeof(MapPointPositionUpdate);
  return bytes;
}

}  // namespace ccm
