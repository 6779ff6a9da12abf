#include "slam_core/map/drift_path.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ccm {
namespace {

struct Flown {
  std::shared_ptr<KeyFrame> kf;
  Eigen::Vector3d centre;  ///< read once: each pose read locks the keyframe
  double path = 0.0;       ///< distance flown from the agent's first keyframe in the map
};

// One agent's keyframes in counter order (keyframes() is sorted by id) with the distance
// flown up to each.
std::vector<Flown> FlownAlong(const std::vector<std::shared_ptr<KeyFrame>>& keyframes, AgentId agent) {
  std::vector<Flown> out;
  for (const auto& kf : keyframes) {
    if (kf->id().agent() != agent) continue;
    const Eigen::Vector3d centre = kf->world_from_cam().translation();
    const double path = out.empty() ? 0.0 : out.back().path + (centre - out.back().centre).norm();
    out.push_back({kf, centre, path});
  }
  return out;
}

// First entry whose keyframe id is not below `id`.
std::vector<Flown>::const_iterator LowerBound(const std::vector<Flown>& flown, KeyframeId id) {
  return std::lower_bound(flown.begin(), flown.end(), id,
                          [](const Flown& f, KeyframeId x) { return f.kf->id() < x; });
}

// The distance flown up to keyframe `id`, if it is in `flown`.
std::optional<double> FlownTo(const std::vector<Flown>& flown, KeyframeId id) {
  const auto it = LowerBound(flown, id);
  if (it == flown.end() || it->kf->id() != id) return std::nullopt;
  return it->path;
}

}  // namespace

std::optional<double> DriftPath(const Map& map, KeyframeId a, KeyframeId b, int min_shared_points) {
  const auto keyframes = map.keyframes();
  const std::vector<Flown> along_a = FlownAlong(keyframes, a.agent());
  if (a.agent() == b.agent()) {
    // Through the keyframes whose counters lie between the two (either end may be gone).
    const auto first = LowerBound(along_a, std::min(a, b));
    const auto end = std::upper_bound(along_a.begin(), along_a.end(), std::max(a, b),
                                      [](KeyframeId x, const Flown& f) { return x < f.kf->id(); });
    return first < end ? (end - 1)->path - first->path : 0.0;
  }
  const std::vector<Flown> along_b = FlownAlong(keyframes, b.agent());
  const auto to_a = FlownTo(along_a, a), to_b = FlownTo(along_b, b);
  if (!to_a || !to_b) return std::nullopt;
  double best = std::numeric_limits<double>::infinity();
  for (const Flown& j : along_a) {
    const double to_junction = std::abs(j.path - *to_a);
    if (to_junction >= best) continue;
    for (const auto& [other, weight] : j.kf->covisibility()) {
      if (other.agent() != b.agent() || weight < min_shared_points) continue;
      if (const auto o = FlownTo(along_b, other)) best = std::min(best, to_junction + std::abs(*to_b - *o));
    }
  }
  if (!std::isfinite(best)) return std::nullopt;
  return best;
}

}  // namespace ccm
