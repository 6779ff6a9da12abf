#include "slam_core/map/drift_path.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>

namespace ccm {
namespace {

struct Flown {
  std::shared_ptr<KeyFrame> kf;
  Eigen::Vector3d centre;  ///< read once: each pose read locks the keyframe
  double path = 0.0;       ///< distance flown from its agent's first keyframe in the map
};

// Every keyframe in id order (keyframes() is sorted by id, so each agent's keyframes form
// one run in counter order) with the distance its agent has flown up to it.
std::vector<Flown> FlownAlong(const std::vector<std::shared_ptr<KeyFrame>>& keyframes) {
  std::vector<Flown> out;
  for (const auto& kf : keyframes) {
    const Eigen::Vector3d centre = kf->world_from_cam().translation();
    const bool same_agent = !out.empty() && out.back().kf->id().agent() == kf->id().agent();
    const double path = same_agent ? out.back().path + (centre - out.back().centre).norm() : 0.0;
    out.push_back({kf, centre, path});
  }
  return out;
}

// First entry whose keyframe id is not below `id`.
std::vector<Flown>::const_iterator LowerBound(const std::vector<Flown>& flown, KeyframeId id) {
  return std::lower_bound(flown.begin(), flown.end(), id,
                          [](const Flown& f, KeyframeId x) { return f.kf->id() < x; });
}

// Index of keyframe `id` in `flown`, if it is there.
std::optional<size_t> IndexOf(const std::vector<Flown>& flown, KeyframeId id) {
  const auto it = LowerBound(flown, id);
  if (it == flown.end() || it->kf->id() != id) return std::nullopt;
  return static_cast<size_t>(it - flown.begin());
}

// Same agent: through its keyframes whose counters lie between the two (either end may be
// gone). Ids sort by agent first, so everything between the two ids is that agent's.
double SameAgentPath(const std::vector<Flown>& flown, KeyframeId a, KeyframeId b) {
  const auto first = LowerBound(flown, std::min(a, b));
  const auto end = std::upper_bound(flown.begin(), flown.end(), std::max(a, b),
                                    [](KeyframeId x, const Flown& f) { return x < f.kf->id(); });
  return first < end ? (end - 1)->path - first->path : 0.0;
}

// Dijkstra over the keyframes: a step to the agent's previous or next keyframe costs the
// distance flown between them, a junction to another agent's keyframe costs nothing.
// Covisibility (a keyframe lock each) is read only for the keyframes the search reaches.
std::optional<double> ShortestRoute(const std::vector<Flown>& flown, size_t from, size_t to, int min_shared_points) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> dist(flown.size(), kInf);
  using Entry = std::pair<double, size_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
  dist[from] = 0.0;
  open.push({0.0, from});
  auto relax = [&](size_t j, double d) {
    if (d < dist[j]) {
      dist[j] = d;
      open.push({d, j});
    }
  };
  while (!open.empty()) {
    const auto [d, i] = open.top();
    open.pop();
    if (i == to) return d;
    if (d > dist[i]) continue;
    const AgentId agent = flown[i].kf->id().agent();
    if (i > 0 && flown[i - 1].kf->id().agent() == agent) relax(i - 1, d + flown[i].path - flown[i - 1].path);
    if (i + 1 < flown.size() && flown[i + 1].kf->id().agent() == agent) {
      relax(i + 1, d + flown[i + 1].path - flown[i].path);
    }
    for (const auto& [other, weight] : flown[i].kf->covisibility()) {
      if (other.agent() == agent || weight < min_shared_points) continue;
      if (const auto j = IndexOf(flown, other)) relax(*j, d);
    }
  }
  return std::nullopt;
}

}  // namespace

std::optional<double> DriftPath(const Map& map, KeyframeId a, KeyframeId b, int min_shared_points) {
  const std::vector<Flown> flown = FlownAlong(map.keyframes());
  if (a.agent() == b.agent()) return SameAgentPath(flown, a, b);
  const auto from = IndexOf(flown, a), to = IndexOf(flown, b);
  if (!from || !to) return std::nullopt;
  return ShortestRoute(flown, *from, *to, min_shared_points);
}

}  // namespace ccm
