// Turns what the VO changed (AgentVo::TakeChanges) into the agent -> server value types:
// keyframes and points the server has not been sent yet go out in full, the others as pose /
// position updates, all relative (keyframe to predecessor and parent, point to its reference
// keyframe). Only the agent's own data is packed; keyframes and points the server shared with
// the agent are the server's. Owned by one thread (the agent's comm module, or ccm_replay's
// agent loop); reads the VO map through its thread-safe accessors while mapping runs.
#pragma once

#include <functional>
#include <optional>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/map/map.h"
#include "slam_core/map/near_duplicate.h"
#include "slam_core/vo/agent_vo.h"

namespace ccm {

/// The full keyframe `id` of `map` relative to its predecessor (the newest older keyframe of
/// the same agent still in the map) and its spanning-tree parent (else its best covisible
/// keyframe). nullopt if absent. `excluded(kf)`: keyframes neither may be (anchors).
std::optional<KeyframeData> PackKeyframe(const Map& map, KeyframeId id, const KeyframeFilter& excluded = nullptr);
/// The full map point `id` relative to its reference keyframe (an own observing keyframe);
/// nullopt if absent or no own keyframe observes it.
/// `excluded(kf)`: own keyframes that must not appear as observer or reference (anchors).
std::optional<MapPointData> PackMapPoint(const Map& map, MapPointId id,
                                         const KeyframeFilter& excluded = nullptr);

struct ChangePackerOptions {
  /// A sent point's new position goes out only if it moved by more than this fraction of
  /// its depth in the reference keyframe (or its reference changed). Local BA nudges every
  /// point of its window each time; most moves are far below what matters to the server,
  /// which refines the points itself, and were most of the uplink.
  double min_point_update_ratio = 0.01;
  /// Data time: a new keyframe leaves only once it is this old, so the keyframes local
  /// mapping culls as redundant soon after creating them (40 % on hall3) never cost uplink;
  /// points wait for their reference keyframe. FlushNext() sends everything at the next Pack
  /// (end of a flight).
  double new_keyframe_delay_s = 0.0;
  /// A new keyframe that nearly duplicates one the server has in full (NearDuplicateOf,
  /// counting only such keyframes as observers) leaves as an anchor only: its poses, ~250 B
  /// instead of ~41 kB. The server's own rule would have dropped its features (half of the
  /// keyframes sent on hall3). Off by default here (distance_ratio 0); ccm_agent's config
  /// turns it on.
  NearDuplicateRule anchor_duplicates{0.0};
};

class ChangePacker {
 public:
  explicit ChangePacker(AgentId agent, ChangePackerOptions options = {}) : agent_(agent), options_(options) {}

  /// Everything changed in `changes.map` since the last call. Keyframes sorted by id.
  AgentBatch Pack(const VoChanges& changes, int64_t stamp_ns);
  /// Send `kf` in full again with the next Pack (the server never acknowledged it), with the
  /// points it observes that this agent created, also in full.
  void Resend(KeyframeId kf) { resend_.insert(kf); }

  /// Keyframes sent (full or as anchors; resends included), and of the first transmissions
  /// those sent as anchors (a resent anchor under loss counted twice here, once on the server).
  size_t keyframes_sent() const { return keyframes_sent_; }
  size_t anchors_sent() const { return anchors_sent_; }
  /// Anchors resent in full because the keyframe they duplicate had left the local map: a
  /// server that lost the anchor counts such a keyframe as full, one that had it as an anchor.
  size_t anchors_resent_in_full() const { return anchors_resent_in_full_; }
  size_t map_points_sent() const { return points_sent_; }
  size_t point_updates_skipped() const { return point_updates_skipped_; }
  /// Ignore the keyframe delay at the next Pack.
  void FlushNext() { flush_ = true; }
  /// Keyframes and points held back by the delay.
  size_t deferred() const { return deferred_kfs_.size() + deferred_points_.size(); }

 private:
  void Forget(const Map& map);
  KeyframeId SharedReference(const Map& map, KeyframeId vo_reference) const;
  /// The server has this keyframe with its features: another agent's (shared with us) or
  /// one of ours sent in full.
  bool ServerHasInFull(KeyframeId id) const;
  /// In `map` as the server sent it (map sharing; own old keyframes come back so too).
  static bool FromServer(const Map& map, KeyframeId id);
  bool IsAnchor(KeyframeId id) const { return anchored_.count(id) > 0; }
  /// `kf` packed in full, or as an anchor if it nearly duplicates a keyframe the server has.
  std::optional<KeyframeData> PackNew(const Map& map, KeyframeId id, bool resend);
  void OmitLinkedObservations(MapPointData* mp) const;
  /// Drops a new keyframe's links to own points that will not leave with it or before it.
  void DropLinksToLaterPoints(const Map& map, KeyframeData* kf) const;

  struct SentPoint {
    KeyframeId reference_kf;
    Eigen::Vector3d position_ref;
  };
  const AgentId agent_;
  const ChangePackerOptions options_;
  std::set<KeyframeId> deferred_kfs_;
  std::set<MapPointId> deferred_points_;
  bool flush_ = false;
  std::unordered_set<KeyframeId> sent_kfs_;
  std::unordered_map<MapPointId, SentPoint> sent_points_;  ///< as the server last got them
  std::unordered_set<KeyframeId> resend_;
  std::unordered_map<KeyframeId, KeyframeId> anchored_;  ///< sent as anchor -> the keyframe it duplicates
  /// Own points each keyframe sent in full linked when it was sent.
  std::unordered_map<KeyframeId, std::unordered_set<MapPointId>> sent_links_;
  MapId segment_;
  size_t keyframes_sent_ = 0, anchors_sent_ = 0, anchors_resent_in_full_ = 0, points_sent_ = 0, point_updates_skipped_ = 0;
  int packs_ = 0;
};

}  // namespace ccm
