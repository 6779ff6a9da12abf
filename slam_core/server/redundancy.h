// Redundant keyframe removal on the server (CCM-SLAM 4.6): pick a random keyframe, look at
// its covisible neighbours; a neighbour is redundant if at least theta of its map points are
// seen by >= 3 other keyframes at the same or a finer scale. A redundant keyframe leaves the
// map (and the place-recognition database, through the caller) but stays as an anchor, its
// pose relative to its strongest neighbour, so later data that refers to it still lands and
// its agent's trajectory keeps it. Never removed: a map's oldest keyframe (gauge), keyframes
// with loop edges, each handler's newest keyframe. Runs while no global BA is pending.
// Synchronous; the caller holds the structure lock shared.
#pragma once

#include <random>
#include <vector>

#include "slam_core/server/server_map.h"

namespace ccm {

struct RedundancyStep {
  KeyframeId checked;                 ///< the random keyframe whose neighbours were tested
  std::vector<KeyframeId> removed;
};

class RedundancyRemover {
 public:
  RedundancyRemover(double theta, uint64_t seed) : theta_(theta), rng_(seed) {}

  /// One step on `map`; `protected_ids` are never removed (the handlers' newest keyframes).
  RedundancyStep Step(ServerMap* map, const std::vector<KeyframeId>& protected_ids);
  /// Whether `kf` is redundant in `map` under theta (exposed for tests).
  bool IsRedundant(const Map& map, const KeyFrame& kf) const;

 private:
  double theta_;
  std::mt19937_64 rng_;
};

}  // namespace ccm
