#include "slam_core/server/outgoing.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <unordered_set>

#include "slam_core/map_ops/point_fusion.h"
#include "slam_core/server/registration.h"

namespace ccm {
namespace {

// The agent's own old keyframes near `base` and looking its way, nearest first.
template <typename OwnOld>
std::vector<std::pair<double, std::shared_ptr<KeyFrame>>> OwnOldKeyframesNear(const Map& map, const KeyFrame& base,
                                                                                AgentId agent,
                                                                                const NeighbourhoodOptions& options,
                                                                                const OwnOld& own_old) {
  std::vector<std::pair<double, std::shared_ptr<KeyFrame>>> near;
  const double depth = MedianSceneDepth(map, base);
  if (!(depth > 0.0)) return near;
  const double radius = options.own_nearby_depth_ratio * depth;
  const double min_cos = std::cos(kNearbyMaxAngleDeg * M_PI / 180.0);
  const Eigen::Vector3d centre = base.camera_center();
  const Eigen::Vector3d axis = base.world_from_cam().rotation() * Eigen::Vector3d::UnitZ();
  for (const auto& kf : map.keyframes()) {
    if (kf->id().agent() != agent || !own_old(*kf)) continue;
    const double distance = (kf->camera_center() - centre).norm();
    if (distance > radius) continue;
    if ((kf->world_from_cam().rotation() * Eigen::Vector3d::UnitZ()).dot(axis) < min_cos) continue;
    near.emplace_back(distance, kf);
  }
  std::sort(near.begin(), near.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return near;
}

}  // namespace

std::optional<ServerMapData> AgentNeighbourhood(const MapStack& stack, AgentId agent, KeyframeId reference_kf,
                                                const NeighbourhoodOptions& options,
                                                const std::unordered_set<KeyframeId>* held) {
  const auto smap = stack.MapHolding(reference_kf);
  if (!smap) return std::nullopt;
  std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  if (smap->retired()) return std::nullopt;
  const Map& map = smap->map();
  const auto world_from_ref = smap->PoseOf(reference_kf);
  if (!world_from_ref) return std::nullopt;
  std::shared_ptr<KeyFrame> base = map.keyframe(reference_kf);
  MapId segment;
  int64_t reference_stamp_ns = 0;
  bool reference_is_anchor = false;
  if (base) {
    if (const auto info = smap->Info(reference_kf)) segment = info->segment;
    reference_stamp_ns = base->stamp_ns();
  } else if (const auto anchor = smap->Anchor(reference_kf)) {
    base = map.keyframe(anchor->base);
    segment = anchor->segment;
    reference_stamp_ns = anchor->stamp_ns;
    reference_is_anchor = true;
  }
  const auto handler = stack.Handler(agent, segment);
  if (!base || !handler || handler->scale <= 0.0) return std::nullopt;
  const double to_vo = 1.0 / handler->scale;
  const SE3 ref_from_world = world_from_ref->inverse();

  ServerMapData data;
  data.reference_kf = reference_kf;
  std::set<KeyframeId> sent;
  // Held, not looked up again: under the shared structure lock another agent's server mapping
  // or the redundancy step may erase a keyframe between the two loops below.
  std::vector<std::shared_ptr<KeyFrame>> sent_kfs;
  // Other agents' keyframes: the agent's own recent covisible keyframes are in its local map
  // already (it made them), and sending them back would double the downlink for nothing.
  // Its own old ones (own_keyframes_after_s) its bounded local map has forgotten: without
  // them, an agent back at a place it flew maps it again. Before any fusion, and without
  // old own keyframes, this is empty and nothing is sent.
  // Age counts from the reference's own time: an agent back at a place it flew makes its
  // keyframes there anchors of the first pass's, and the base is then one of those.
  const auto own_old = [&](const KeyFrame& kf) {
    return options.own_keyframes_after_s > 0.0 &&
           static_cast<double>(reference_stamp_ns - kf.stamp_ns()) * 1e-9 > options.own_keyframes_after_s;
  };
  const auto add = [&](KeyframeId id, const std::shared_ptr<KeyFrame>& kf) {
    ServerKeyframe skf;
    skf.id = id;
    skf.stamp_ns = kf->stamp_ns();
    skf.held = held != nullptr && held->count(id) > 0;
    if (!skf.held) {
      skf.camera = kf->camera_ptr();
      skf.features = kf->features_ptr();
    }
    skf.ref_from_cam = ScaledPose(ref_from_world * kf->world_from_cam(), to_vo);
    data.keyframes.push_back(skf);
    sent.insert(id);
    sent_kfs.push_back(kf);
  };
  std::vector<KeyframeId> candidates;
  // An anchor's base is the keyframe nearest to the agent of all: with old own keyframes asked
  // for, it goes first (the agent had it when it made the anchor, so otherwise it has it still).
  if (reference_is_anchor && options.own_keyframes_after_s > 0.0) candidates.push_back(base->id());
  for (const KeyframeId id : base->BestCovisible(8 * options.keyframes + 1)) candidates.push_back(id);
  for (const KeyframeId id : candidates) {
    if (id == reference_kf || static_cast<int>(data.keyframes.size()) >= options.keyframes) continue;
    const auto kf = map.keyframe(id);
    if (!kf || (id.agent() == agent && !own_old(*kf))) continue;
    add(id, kf);
  }
  if (options.own_keyframes_after_s > 0.0 && options.own_nearby_depth_ratio > 0.0 &&
      static_cast<int>(data.keyframes.size()) < options.keyframes) {
    for (const auto& [distance, kf] : OwnOldKeyframesNear(map, *base, agent, options, own_old)) {
      if (static_cast<int>(data.keyframes.size()) >= options.keyframes) break;
      if (kf->id() != reference_kf && !sent.count(kf->id())) add(kf->id(), kf);
    }
  }
  if (data.keyframes.empty()) return std::nullopt;
  std::unordered_set<MapPointId> seen;
  for (const auto& kf : sent_kfs) {
    for (const auto& mp : PointsOf(map, *kf)) {
      if (data.map_points.size() >= options.max_points) break;
      if (!seen.insert(mp->id()).second) continue;
      ServerMapPoint smp;
      smp.id = mp->id();
      smp.position_ref = (ref_from_world * mp->position()) * to_vo;
      for (const auto& [kf, idx] : mp->observations()) {
        // The agent can attach an observation only to keyframes it has: the ones sent now
        // and its own.
        if (sent.count(kf) || kf.agent() == agent) smp.observations.emplace_back(kf, idx);
      }
      data.map_points.push_back(std::move(smp));
    }
  }
  return data;
}

}  // namespace ccm
