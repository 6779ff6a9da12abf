#include "slam_core/map/drift_path.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace ccm {

namespace {

// Through one agent's keyframes whose counters lie between a's and b's (either may be gone).
double SameAgentPath(const Map& map, KeyframeId a, KeyframeId b) {
  const uint64_t lo = std::min(a.counter(), b.counter()), hi = std::max(a.counter(), b.counter());
  double path = 0.0;
  std::optional<Eigen::Vector3d> last;
  for (const auto& kf : map.keyframes()) {  // sorted by id: one agent's by counter
    if (kf->id().agent() != a.agent() || kf->id().counter() < lo || kf->id().counter() > hi) continue;
    const Eigen::Vector3d centre = kf->world_from_cam().translation();
    if (last) path += (centre - *last).norm();
    last = centre;
  }
  return path;
}

}  // namespace

std::optional<double> DriftPath(const Map& map, KeyframeId a, KeyframeId b, int min_shared_points) {
  if (a.agent() == b.agent()) return SameAgentPath(map, a, b);
  // Distance flown up to each keyframe of the two agents, in counter order (keyframes()
  // is sorted by id, i.e. per agent by counter).
  std::unordered_map<KeyframeId, double> flown;
  std::vector<std::shared_ptr<KeyFrame>> a_side;
  std::unordered_map<AgentId, std::optional<Eigen::Vector3d>> last;
  std::unordered_map<AgentId, double> total;
  for (const auto& kf : map.keyframes()) {
    const AgentId agent = kf->id().agent();
    if (agent != a.agent() && agent != b.agent()) continue;
    const Eigen::Vector3d centre = kf->world_from_cam().translation();
    if (last[agent]) total[agent] += (centre - *last[agent]).norm();
    last[agent] = centre;
    flown[kf->id()] = total[agent];
    if (agent == a.agent()) a_side.push_back(kf);
  }
  const auto fa = flown.find(a), fb = flown.find(b);
  if (fa == flown.end() || fb == flown.end()) return std::nullopt;
  double best = std::numeric_limits<double>::infinity();
  for (const auto& kf : a_side) {
    const double to_junction = std::abs(flown[kf->id()] - fa->second);
    if (to_junction >= best) continue;
    for (const auto& [other, weight] : kf->covisibility()) {
      if (other.agent() != b.agent() || weight < min_shared_points) continue;
      const auto fo = flown.find(other);
      if (fo != flown.end()) best = std::min(best, to_junction + std::abs(fb->second - fo->second));
    }
  }
  if (!std::isfinite(best)) return std::nullopt;
  return best;
}

}  // namespace ccm
