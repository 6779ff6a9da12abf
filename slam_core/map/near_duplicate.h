// Forster et al.'s near-duplicate keyframe test, shared by the server (which keeps such a
// keyframe only as a pose anchor) and the agent (which then sends only that anchor instead
// of the full keyframe: the server would have dropped its features anyway).
#pragma once

#include <functional>

#include "slam_core/map/map.h"

namespace ccm {

struct NearDuplicateRule {
  /// A covisible keyframe closer than this share of `kf`'s median scene depth ... (0: off)
  double distance_ratio = 0.10;
  /// ... whose optical axis differs by less than this ...
  double max_angle_deg = 10.0;
  /// ... and at least this share of `kf`'s points keep >= 2 other observers.
  double min_covered = 0.9;
  /// How many of `kf`'s best covisible keyframes are looked at (-1: all of them).
  int candidates = 5;
  bool enabled() const { return distance_ratio > 0.0; }
  /// Empty or what is wrong ("distance_ratio must be in [0, 1)").
  std::string Validate() const;
};

/// Angle between the optical axes of two keyframes [deg].
double OpticalAxisAngleDeg(const KeyFrame& a, const KeyFrame& b);

/// Which keyframes count (null: all).
using KeyframeFilter = std::function<bool(KeyframeId)>;

/// The covisible keyframe (among the rule's `candidates` best) that `kf` nearly duplicates
/// under `rule`, or Invalid. `base` says which keyframes may be the duplicated one,
/// `observer` which count as other observers of its points (the agent: keyframes the server
/// has in full, and keyframes that will still be sent).
KeyframeId NearDuplicateOf(const Map& map, const KeyFrame& kf, const NearDuplicateRule& rule,
                           const KeyframeFilter& base = nullptr, const KeyframeFilter& observer = nullptr);

}  // namespace ccm
