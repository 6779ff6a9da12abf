// Keeps the agent's local map bounded as CCM-SLAM specifies: the reference keyframe and
// the N-1 most recent keyframes stay; older keyframes leave once the server has them for
// good (acknowledged and persisted: a restarted server may need the others again); the
// others wait in a buffer of up to B. Over N+B, keyframes that came from other agents (the
// server has them) go first, then the oldest buffered ones that the server processed but
// has not saved yet (lost only if it crashes before its next save), then the oldest
// unacknowledged ones, which is data loss. Both are counted. Owned by the local-mapping
// side of the agent VO.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <unordered_set>

#include "slam_core/map/map.h"

namespace ccm {

/// Who decides that the server has a keyframe. The real one lives in the agent's comm
/// module; tests and standalone runs use AckAll / AckNone.
class AckSource {
 public:
  virtual ~AckSource() = default;
  /// The server processed `kf`.
  virtual bool IsAcked(KeyframeId kf) const = 0;
  /// ... and saved it where a restart finds it (a server that saves nothing: when processed).
  virtual bool IsPersisted(KeyframeId kf) const { return IsAcked(kf); }
};

class AckAll final : public AckSource {
 public:
  bool IsAcked(KeyframeId) const override { return true; }
};

class AckNone final : public AckSource {
 public:
  bool IsAcked(KeyframeId) const override { return false; }
};

struct LocalMapBoundOptions {
  int max_keyframes = 50;        ///< N: reference KF + N-1 most recent always stay
  int max_unacked_buffer = 50;   ///< B: extra unacknowledged KFs kept for the server
  std::string Validate() const;
};

/// Cumulative counts of what trimming removed.
struct TrimStats {
  int64_t removed_acked = 0;     ///< own KFs the server already had (acknowledged and persisted)
  int64_t removed_foreign = 0;   ///< KFs received from other agents via the server
  int64_t removed_unpersisted = 0;  ///< own KFs acknowledged, not yet persisted: lost if the server crashes now
  int64_t removed_lost = 0;      ///< unacknowledged own KFs dropped: lost for the server
};

class LocalMapBound {
 public:
  LocalMapBound(AgentId own_agent, LocalMapBoundOptions options);

  /// Records insertion order (recency). Call for every keyframe added to the map;
  /// `from_server`: it came from the server (map sharing), which has it, also when it is
  /// one of the agent's own old keyframes sent back: it is trimmed like another agent's.
  void OnKeyframeInserted(KeyframeId kf, bool from_server = false);
  /// Erases keyframes from `map` per the rules above; `reference_kf` is never erased.
  void Trim(Map* map, KeyframeId reference_kf, const AckSource& acks);

  const TrimStats& stats() const { return stats_; }
  const LocalMapBoundOptions& options() const { return options_; }

 private:
  bool EraseFromMap(Map* map, KeyframeId kf);

  const AgentId own_agent_;
  const LocalMapBoundOptions options_;
  std::deque<KeyframeId> recency_;  // oldest first
  std::unordered_set<KeyframeId> returned_;  // own keyframes the server sent back (in the map)
  TrimStats stats_;
};

}  // namespace ccm
