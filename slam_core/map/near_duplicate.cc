#include "slam_core/map/near_duplicate.h"

#include <algorithm>
#include <cmath>

namespace ccm {

std::string NearDuplicateRule::Validate() const {
  if (!(distance_ratio >= 0.0 && distance_ratio < 1.0)) return "distance_ratio must be in [0, 1)";
  if (!(max_angle_deg >= 0.0 && max_angle_deg <= 180.0)) return "max_angle_deg must be in [0, 180]";
  if (!(min_covered >= 0.0 && min_covered <= 1.0)) return "min_covered must be in [0, 1]";
  if (candidates == 0 || candidates < -1) return "candidates must be >= 1 (-1: all)";
  return "";
}

double OpticalAxisAngleDeg(const KeyFrame& a, const KeyFrame& b) {
  const Eigen::Vector3d za = a.world_from_cam().rotation() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d zb = b.world_from_cam().rotation() * Eigen::Vector3d::UnitZ();
  return std::acos(std::clamp(za.dot(zb), -1.0, 1.0)) * 180.0 / M_PI;
}

KeyframeId NearDuplicateOf(const Map& map, const KeyFrame& kf, const NearDuplicateRule& rule,
                           const KeyframeFilter& base, const KeyframeFilter& observer) {
  if (!rule.enabled()) return KeyframeId::Invalid();
  const double depth = MedianSceneDepth(map, kf);
  if (depth <= 0.0) return KeyframeId::Invalid();
  KeyframeId dup;
  for (const KeyframeId id : kf.BestCovisible(rule.candidates)) {
    if (base && !base(id)) continue;
    const auto n = map.keyframe(id);
    if (!n || n->bad()) continue;
    if ((n->camera_center() - kf.camera_center()).norm() < rule.distance_ratio * depth &&
        OpticalAxisAngleDeg(*n, kf) < rule.max_angle_deg) {
      dup = id;
      break;
    }
  }
  if (!dup.valid()) return dup;
  // Only if dropping its observations orphans almost nothing.
  int total = 0, covered = 0;
  for (const MapPointId id : kf.map_points()) {
    if (!id.valid()) continue;
    const auto mp = map.map_point(id);
    if (!mp || mp->bad()) continue;
    ++total;
    int others = 0;
    for (const auto& obs : mp->observations()) others += obs.first != kf.id() && (!observer || observer(obs.first));
    covered += others >= 2;
  }
  return total > 0 && covered >= rule.min_covered * total ? dup : KeyframeId::Invalid();
}

}  // namespace ccm
