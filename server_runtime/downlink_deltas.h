// Downlink deltas (issue 30, docs/protocol.md "Map sharing back"): what the server leaves out
// of an agent's neighbourhood because the agent holds it already. The agent's heartbeat says
// which server keyframes its local map holds as of the newest server message it integrated;
// those, and the keyframes sent in full after that message, go as poses only; a point sent in
// full before that no keyframe going in full observes goes as a position only. An agent that
// never reports integrating anything (a recording played by ccm_fleet, an agent before its
// first server data) always gets everything in full. One per agent; ServerComm's comm thread.
#pragma once

#include <cstdint>
#include <deque>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "slam_core/exchange/server_map_data.h"

namespace ccm::server {

class DownlinkDeltas {
 public:
  /// Keyframes sent in full that the agent never reports integrating count as held this long
  /// (a lost neighbourhood is sent in full again after it).
  static constexpr int64_t kInFlightNs = 10'000'000'000;
  /// A point not in any neighbourhood for this long is forgotten (sent in full if it comes
  /// back): the set stays as large as the agent's recent surroundings, not the whole map,
  /// on long missions; an agent has usually trimmed such a point by then anyway.
  static constexpr int64_t kForgetPointNs = 60'000'000'000;

  /// The agent's heartbeat.
  void OnHoldings(const ServerHoldings& holdings);
  /// What counts as held for the next neighbourhood.
  std::unordered_set<KeyframeId> HeldKeyframes() const;
  /// Marks the points of `data` (its keyframes already marked) that go as positions only.
  void MarkHeldPoints(ServerMapData* data) const;
  /// A neighbourhood written at `stamp_ns` (the message's stamp, which the agent echoes).
  void RecordSent(int64_t stamp_ns, const ServerMapData& data);
  /// Points it remembers as sent in full.
  size_t points_remembered() const { return points_sent_.size(); }

 private:
  bool reports_ = false;
  std::unordered_set<KeyframeId> held_;
  std::deque<std::pair<int64_t, std::vector<KeyframeId>>> sent_since_;
  /// Points sent in full, with the stamp of the last neighbourhood that held them.
  std::unordered_map<MapPointId, int64_t> points_sent_;
  int64_t last_prune_ns_ = 0;
};

}  // namespace ccm::server
