// Server mapping of a newly registered keyframe: covisibility connections, fusion of
// duplicate points with its neighbourhood (two covisibility hops, as ORB-SLAM's
// SearchInNeighbors; neighbours may be other agents' keyframes once maps share points), a
// local BA where the keyframe joined data the agent did not optimize itself (another agent's
// keyframes or an older part of the map), and Forster et al.'s near-duplicate rejection.
// Synchronous and stateless; the caller's handler thread runs it with the map's structure
// lock held shared.
#pragma once

#include <memory>

#include "slam_core/server/server_map.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct ServerMappingReport {
  double fusion_ms = 0.0;    ///< covisibility + duplicate-point fusion
  double local_ba_ms = 0.0;
  int points_fused = 0;
  int observations_linked = 0;
  bool local_ba = false;
  int local_ba_outliers = 0;
  /// Rejected as a near-duplicate: anchored to `duplicate_of` and removed from the map.
  bool skipped = false;
  KeyframeId duplicate_of;
};

class ServerMapper {
 public:
  explicit ServerMapper(const ServerMappingOptions& options) : options_(options) {}

  ServerMappingReport Process(ServerMap* map, const std::shared_ptr<KeyFrame>& kf) const;

 private:
  void FuseWithNeighbourhood(ServerMap* map, const std::shared_ptr<KeyFrame>& kf, ServerMappingReport* r) const;
  bool NeedsLocalBa(const KeyFrame& kf) const;
  KeyframeId NearDuplicateOf(const Map& map, const KeyFrame& kf) const;

  const ServerMappingOptions options_;
};

}  // namespace ccm
