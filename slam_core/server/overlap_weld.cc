#include "slam_core/server/overlap_weld.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>
#include <utility>
#include <vector>

namespace ccm {
namespace {

struct Pose {
  std::shared_ptr<KeyFrame> kf;
  Eigen::Vector3d centre, axis;
};

// The map's usable keyframes inside side `a` (inside = true) or outside it.
std::vector<Pose> PosesOf(const Map& map, const std::set<KeyframeId>& a, bool inside) {
  std::vector<Pose> out;
  for (const auto& kf : map.keyframes()) {
    if (a.count(kf->id()) != (inside ? 1u : 0u) || kf->bad() || kf->num_keypoints() == 0) continue;
    const SE3 w = kf->world_from_cam();
    out.push_back({kf, w.translation(), w.rotation() * Eigen::Vector3d::UnitZ()});
  }
  return out;
}

}  // namespace

OverlapWeldReport WeldOverlap(Map* map, const std::set<KeyframeId>& a, const OverlapWeldOptions& options) {
  OverlapWeldReport report;
  const std::vector<Pose> targets = PosesOf(*map, a, true), sources = PosesOf(*map, a, false);
  if (targets.empty() || sources.empty()) return report;
  const double min_cos = std::cos(options.max_axis_deg * M_PI / 180.0);
  std::unordered_set<KeyframeId> touched;
  for (const Pose& t : targets) {
    const double depth = MedianSceneDepth(*map, *t.kf);
    if (depth <= 0.0) continue;
    const double max_d2 = std::pow(options.max_centre_depth_ratio * depth, 2);
    std::vector<std::pair<double, const Pose*>> near;
    for (const Pose& s : sources) {
      const double d2 = (s.centre - t.centre).squaredNorm();
      if (d2 <= max_d2 && s.axis.dot(t.axis) >= min_cos) near.emplace_back(d2, &s);
    }
    if (near.empty()) continue;
    const size_t n = std::min<size_t>(near.size(), static_cast<size_t>(options.max_sources));
    std::partial_sort(near.begin(), near.begin() + n, near.end(),
                      [](const auto& x, const auto& y) { return x.first < y.first; });
    std::vector<std::shared_ptr<MapPoint>> points;
    std::unordered_set<MapPointId> seen;
    for (size_t i = 0; i < n; ++i) {
      for (const auto& mp : PointsOf(*map, *near[i].second->kf)) {
        if (seen.insert(mp->id()).second) points.push_back(mp);
      }
      touched.insert(near[i].second->kf->id());
    }
    const int before = report.fusion.fused + report.fusion.linked;
    FusePointsIntoKeyframe(map, t.kf, GridOf(*t.kf), points, options.radius_px, &report.fusion);
    ++report.targets;
    if (report.fusion.fused + report.fusion.linked > before) touched.insert(t.kf->id());
  }
  // A merged point's observers gained (or changed) covisibility, not just the target.
  for (const auto& [old_id, keep] : report.fusion.replaced) {
    if (const auto mp = map->map_point(keep)) {
      for (const auto& [kf, idx] : mp->observations()) touched.insert(kf);
    }
  }
  for (const KeyframeId id : touched) map->UpdateConnections(id);
  return report;
}

}  // namespace ccm
