#include "slam_core/vo/server_data_integrator.h"

#include <set>

namespace ccm {
namespace {

void IntegrateKeyframes(const ServerMapData& data, const SE3& world_from_ref, AgentId own_agent,
                        const std::shared_ptr<const ScalePyramid>& pyramid, Map* map, LocalMapBound* bound,
                        ServerDataStats* stats, std::set<KeyframeId>* touched) {
  for (const ServerKeyframe& skf : data.keyframes) {
    const auto existing = map->keyframe(skf.id);
    if (skf.held && !existing) {
      // Trimmed since the agent reported holding it: its next report says so and the
      // server sends it in full again. Its points' observations of it are skipped below.
      ++stats->keyframes_not_held;
      continue;
    }
    if (!skf.held && (!skf.features || !skf.camera)) continue;
    const SE3 world_from_cam = world_from_ref * skf.ref_from_cam;
    if (existing) {
      // The agent's own keyframes keep the VO estimate (the agent stays autonomous);
      // keyframes of other agents follow the server, which optimizes them globally.
      if (skf.id.agent() != own_agent) {
        existing->SetWorldFromCam(world_from_cam);
        ++stats->keyframes_updated;
      }
      continue;
    }
    auto kf = std::make_shared<KeyFrame>(skf.id, skf.stamp_ns, skf.camera, skf.features, pyramid, world_from_cam);
    kf->MarkFromServer();
    map->AddKeyframe(kf);
    bound->OnKeyframeInserted(skf.id, /*from_server=*/true);
    touched->insert(skf.id);
    ++stats->keyframes_added;
  }
}

void IntegratePoints(const ServerMapData& data, const SE3& world_from_ref, AgentId own_agent, Map* map,
                     ServerDataStats* stats, std::set<KeyframeId>* touched) {
  for (const ServerMapPoint& smp : data.map_points) {
    const Eigen::Vector3d p_w = world_from_ref * smp.position_ref;
    auto mp = map->map_point(smp.id);
    if (smp.held) {
      // Position only: the agent has its descriptor and observations (or dropped it: its
      // keyframe comes in full again once the agent no longer reports holding it).
      if (!mp) {
        ++stats->points_not_held;
      } else if (smp.id.agent() != own_agent) {
        mp->SetPosition(p_w);
        map->UpdateMapPointAppearance(smp.id);
        ++stats->points_updated;
      }
      continue;
    }
    if (!mp) {
      if (smp.observations.empty()) continue;
      // No descriptor on the wire: UpdateMapPointAppearance below takes it from the
      // observing keyframes' keypoints; a point left without one is erased.
      mp = std::make_shared<MapPoint>(smp.id, p_w, smp.observations.front().first, OrbDescriptor{});
      mp->MarkFromServer();
      map->AddMapPoint(mp);
      ++stats->points_added;
    } else if (smp.id.agent() != own_agent) {
      mp->SetPosition(p_w);
      ++stats->points_updated;
    }
    for (const auto& [kf_id, idx] : smp.observations) {
      if (!mp->KeypointIn(kf_id) && map->AddObservation(kf_id, idx, smp.id)) {
        ++stats->observations_added;
        touched->insert(kf_id);
      }
    }
    if (mp->num_observations() == 0) {
      map->EraseMapPoint(smp.id);  // none of its keyframes is in the local map
    } else {
      map->UpdateMapPointAppearance(smp.id);
    }
  }
}

}  // namespace

void IntegrateServerData(const ServerMapData& data, AgentId own_agent, const std::shared_ptr<const ScalePyramid>& pyramid,
                         Map* map, LocalMapBound* bound, ServerDataStats* stats) {
  const auto ref = map->keyframe(data.reference_kf);
  if (!ref) {
    ++stats->messages_stale;
    return;
  }
  const SE3 world_from_ref = ref->world_from_cam();
  std::set<KeyframeId> touched;
  IntegrateKeyframes(data, world_from_ref, own_agent, pyramid, map, bound, stats, &touched);
  IntegratePoints(data, world_from_ref, own_agent, map, stats, &touched);
  for (const KeyframeId kf : touched) map->UpdateConnections(kf);
  ++stats->messages_applied;
}

}  // namespace ccm
