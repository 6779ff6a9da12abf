// Turns what the VO changed (AgentVo::TakeChanges) into the agent -> server value types:
// keyframes and points the server has not been sent yet go out in full, the others as pose /
// position updates, all relative (keyframe to predecessor and parent, point to its reference
// keyframe). Only the agent's own data is packed; keyframes and points the server shared with
// the agent are the server's. Owned by one thread (the agent's comm module, or ccm_replay's
// agent loop); reads the VO map through its thread-safe accessors while mapping runs.
#pragma once

#include <optional>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/map/map.h"
#include "slam_core/vo/agent_vo.h"

namespace ccm {

/// The full keyframe `id` of `map` relative to its predecessor (the newest older keyframe of
/// the same agent still in the map) and its spanning-tree parent. nullopt if absent.
std::optional<KeyframeData> PackKeyframe(const Map& map, KeyframeId id);
/// The full map point `id` relative to its reference keyframe (an own observing keyframe);
/// nullopt if absent or no own keyframe observes it.
std::optional<MapPointData> PackMapPoint(const Map& map, MapPointId id);

class ChangePacker {
 public:
  /// `min_point_update_ratio`: a sent point's new position goes out only if it moved by more
  /// than this fraction of its depth in the reference keyframe (or its reference changed).
  /// Local BA nudges every point of its window each time; most moves are far below what
  /// matters to the server, which refines the points itself, and were most of the uplink.
  /// `new_keyframe_delay_s` (data time): a new keyframe leaves only once it is this old, so
  /// the keyframes local mapping culls as redundant soon after creating them (40 % on hall3)
  /// never cost uplink; points wait for their reference keyframe. FlushNext() sends
  /// everything at the next Pack (end of a flight).
  explicit ChangePacker(AgentId agent, double min_point_update_ratio = 0.01, double new_keyframe_delay_s = 0.0)
      : agent_(agent), min_point_update_ratio_(min_point_update_ratio), new_keyframe_delay_s_(new_keyframe_delay_s) {}

  /// Everything changed in `changes.map` since the last call. Keyframes sorted by id.
  AgentBatch Pack(const VoChanges& changes, int64_t stamp_ns);
  /// Send `kf` in full again with the next Pack (the server never acknowledged it), with the
  /// points it observes that this agent created, also in full.
  void Resend(KeyframeId kf) { resend_.insert(kf); }

  size_t keyframes_sent() const { return keyframes_sent_; }
  size_t map_points_sent() const { return points_sent_; }
  size_t point_updates_skipped() const { return point_updates_skipped_; }
  /// Ignore the keyframe delay at the next Pack.
  void FlushNext() { flush_ = true; }
  /// Keyframes and points held back by the delay.
  size_t deferred() const { return deferred_kfs_.size() + deferred_points_.size(); }

 private:
  void Forget(const Map& map);
  KeyframeId SharedReference(const Map& map, KeyframeId vo_reference) const;

  struct SentPoint {
    KeyframeId reference_kf;
    Eigen::Vector3d position_ref;
  };
  const AgentId agent_;
  const double min_point_update_ratio_;
  const double new_keyframe_delay_s_;
  std::set<KeyframeId> deferred_kfs_;
  std::set<MapPointId> deferred_points_;
  bool flush_ = false;
  std::unordered_set<KeyframeId> sent_kfs_;
  std::unordered_map<MapPointId, SentPoint> sent_points_;  ///< as the server last got them
  std::unordered_set<KeyframeId> resend_;
  MapId segment_;
  size_t keyframes_sent_ = 0, points_sent_ = 0, point_updates_skipped_ = 0;
  int packs_ = 0;
};

}  // namespace ccm
