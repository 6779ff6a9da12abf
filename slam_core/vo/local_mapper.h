// Local mapping: inserts keyframes from tracking into the map, creates new points by
// triangulation with covisible keyframes, fuses duplicates, runs local bundle adjustment,
// culls bad points and redundant keyframes and keeps the map within N + B keyframes.
// Synchronous: the runtime's mapping thread (or the caller, in synchronous mode) calls
// Process() for each job.
#pragma once

#include <deque>
#include <memory>

#include "slam_core/vo/local_map_bound.h"
#include "slam_core/exchange/server_map_data.h"
#include "slam_core/vo/tracker.h"

namespace ccm {

struct MappingStats {
  int64_t keyframes_processed = 0;
  int64_t points_created = 0;
  int64_t points_culled = 0;
  int64_t points_fused = 0;
  int64_t keyframes_culled = 0;
};

class LocalMapper {
 public:
  LocalMapper(VoShared* shared, const AckSource* acks);

  void Process(const KeyframeJob& job);
  /// Integrates server data into `map` (the segment it was received for).
  void ApplyServerData(Map* map, const ServerMapData& data);

  const MappingStats& stats() const { return stats_; }
  const TrimStats& trim_stats() const { return bound_.stats(); }
  const ServerDataStats& server_stats() const { return server_stats_; }
  /// Keyframes that left the map (trimmed or culled) with their last pose: kept so the
  /// standalone tool can write the full keyframe trajectory.
  const std::vector<std::pair<KeyframeId, std::pair<int64_t, SE3>>>& retired_keyframes() const { return retired_; }

 private:
  void InsertKeyframe(Map* map, const KeyframeJob& job);
  void CullRecentPoints(Map* map);
  void TriangulateNewPoints(Map* map, const std::shared_ptr<KeyFrame>& kf);
  void FuseDuplicates(Map* map, const std::shared_ptr<KeyFrame>& kf);
  void LocalBundleAdjustment(Map* map, const std::shared_ptr<KeyFrame>& kf);
  void CullRedundantKeyframes(Map* map, const std::shared_ptr<KeyFrame>& kf);
  void Retire(const std::shared_ptr<KeyFrame>& kf);

  VoShared* shared_;
  const AckSource* acks_;
  LocalMapBound bound_;
  MapId current_map_;
  std::deque<std::pair<MapPointId, int64_t>> recent_points_;  // (point, kf_counter_ at creation)
  int64_t kf_counter_ = 0;
  MappingStats stats_;
  ServerDataStats server_stats_;
  std::vector<std::pair<KeyframeId, std::pair<int64_t, SE3>>> retired_;
};

}  // namespace ccm
