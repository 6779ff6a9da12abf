// Redundant keyframe removal on the server (CCM-SLAM 4.6): pick a random keyframe, look at
// its covisible neighbours; a neighbour is redundant if at least theta of its map points are
// seen by >= 3 other keyframes at the same or a finer scale. A redundant keyframe leaves the
// map (and the place-recognition database, through the caller) but stays as an anchor, its
// pose relative to its strongest neighbour, so later data that refers to it still lands and
// its agent's trajectory keeps it. Never removed: a map's oldest keyframe (gauge), keyframes
// with loop edges, each handler's newest keyframe. Runs while no global BA is pending.
// Also (RedundancyOptions::revisit_*, on by default) a neighbour that nearly duplicates a
// keyframe of an earlier pass is redundant, anchored to that keyframe: repeated passes then
// add little to the map once a loop or fusion has joined them to the first.
// RedundancyRemover is one step on one map (the caller holds its structure lock shared);
// RedundancyStage is the back-end's stage around it (which map, which keyframes protected).
#pragma once

#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "slam_core/server/map_stack.h"
#include "slam_core/server/server_map.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct RedundancyStep {
  KeyframeId checked;                 ///< the random keyframe whose neighbours were tested
  std::vector<KeyframeId> removed;
  int refused = 0;  ///< candidates kept because most of their links disagree with every pose
};

class RedundancyRemover {
 public:
  explicit RedundancyRemover(const RedundancyOptions& options) : options_(options), rng_(options.seed) {}

  /// One step on `map`; `protected_ids` are never removed (the handlers' newest keyframes).
  RedundancyStep Step(ServerMap* map, const std::vector<KeyframeId>& protected_ids);
  /// Whether `kf` is redundant in `map` under theta (exposed for tests).
  bool IsRedundant(const Map& map, const KeyFrame& kf) const;
  /// The keyframe of an earlier pass that `kf` nearly duplicates under the revisit rule,
  /// with at least `min_covered` of its points keeping two other observers, or Invalid
  /// (also when the rule is off).
  KeyframeId RevisitOf(const Map& map, const KeyFrame& kf, double min_covered) const;
  /// The end of a run (the agents fly no further, so revisit_settle_s holds nothing back):
  /// every keyframe of `map`, oldest first, that nearly duplicates an earlier pass leaves as
  /// its anchor, not only the neighbours of random picks, under revisit_sweep_min_covered.
  /// The CCM-SLAM rule is not swept; nothing is when redundancy removal is off (`enabled`).
  RedundancyStep SweepRevisits(ServerMap* map, const std::vector<KeyframeId>& protected_ids) const;

 private:
  /// Whether `kf` may leave at all (not the gauge, protected, bad or on a loop edge).
  static bool Removable(const KeyFrame& kf, KeyframeId oldest, const std::vector<KeyframeId>& protected_ids);
  /// Moves `kf` out of the map into an anchor on `base`, at its pose refined against its
  /// points (AnchorPose); `kf` stays (counted in step->refused) if most of its links disagree.
  static void MakeAnchor(ServerMap* map, const KeyFrame& kf, const KeyFrame& base, RedundancyStep* step);

  RedundancyOptions options_;
  std::mt19937_64 rng_;
};

/// The optimization thread's redundancy step: round-robin over the maps of `stack` with at
/// least min_map_keyframes keyframes, one RedundancyRemover step on the next of them under its
/// shared structure lock, every handler's newest keyframe of that map protected.
/// Synchronous; one thread at a time.
class RedundancyStage {
 public:
  RedundancyStage(const RedundancyOptions& options, MapStack* stack);
  /// Returns the keyframes removed (often none). `on_removed` is called for each while the
  /// map's structure lock is still held, so the place-recognition database drops it before
  /// a loop or fusion could see the map without it.
  std::vector<KeyframeId> Step(const std::function<void(KeyframeId)>& on_removed);
  /// RedundancyRemover::SweepRevisits on `map` (any size), handlers' newest keyframes protected.
  std::vector<KeyframeId> SweepRevisits(MapId map, const std::function<void(KeyframeId)>& on_removed);

 private:
  /// `run` on `smap` (if live) under its shared structure lock, its handlers' newest
  /// keyframes protected; reports each removed keyframe to `on_removed` before unlocking.
  using MapRun = std::function<RedundancyStep(ServerMap*, const std::vector<KeyframeId>& protected_ids)>;
  std::vector<KeyframeId> OnMap(const std::shared_ptr<ServerMap>& smap,
                                const std::function<void(KeyframeId)>& on_removed, const MapRun& run);

  const int min_map_keyframes_;
  MapStack* stack_;
  RedundancyRemover remover_;
  size_t next_ = 0;  ///< round-robin position over the maps
};

}  // namespace ccm
