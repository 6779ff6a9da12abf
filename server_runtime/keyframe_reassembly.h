// Reassembly of the agents' data streams into back-end batches: the stage of ccm_server's
// comm thread between conversion (runtime_common/msg_conversion.h, already validated) and
// the back-end's per-agent queues. No DDS and no clock of its own (the caller passes `now`),
// so every rule below has a unit test (tests/server_runtime/keyframe_reassembly_test.cpp).
//  * Keyframes wait for their points. Keyframes and points travel on separate reliable
//    streams, so on a lossy link a keyframe often arrives before the points it created.
//    Registered without them it has nothing to refine against, and place recognition (which
//    runs right after registration) would verify it without 3-D points and miss the match
//    (measured: no fusion at 20 % loss). A keyframe is held until every point of its own
//    agent it links has arrived, at most max_keyframe_hold; each agent's keyframes leave in
//    arrival order (a later complete one waits behind an earlier incomplete one).
//  * Updates that overtake their data are kept. The BEST_EFFORT update streams have no
//    repair delay, so the first local-BA refinement of a keyframe often arrives before the
//    keyframe itself, and the back-end would ignore it (measured: 2-4x the loss-free ATE).
//    Such an update is kept (the latest wins) and applied when the full data arrives; an
//    update for a keyframe still held changes the held keyframe.
//  * A resend of a keyframe that is still held replaces it (the agent resends what went
//    unacknowledged; the copy must not be registered twice).
//  * "Arrived" is remembered per agent for seen_window; ids older than the oldest forgotten
//    one count as arrived (a keyframe rarely links points that old, and if it does it waits
//    at most max_keyframe_hold).
// Not thread-safe: one owner (the comm thread).
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "slam_core/exchange/agent_data.h"

namespace ccm::server {

/// The batches one intake cycle fills: one per (agent, segment), submitted in that order.
class BatchSet {
 public:
  AgentBatch& For(AgentId agent, MapId segment);
  bool empty() const { return batches_.empty(); }
  /// Every batch, ordered by agent then segment; the set is empty afterwards.
  std::vector<AgentBatch> Take();

 private:
  std::map<std::pair<AgentId, uint64_t>, AgentBatch> batches_;
};

struct ReassemblyOptions {
  std::chrono::milliseconds max_keyframe_hold{1500};
  std::chrono::seconds seen_window{120};
  size_t max_early_updates = 65536;  ///< per agent and kind; a flood of unknown ids clears them
};

class KeyframeReassembly {
 public:
  using Clock = std::chrono::steady_clock;
  enum class UpdateFate {
    kBatched,        ///< its data was seen: goes to the back-end now
    kAppliedToHeld,  ///< changed a keyframe still held here
    kKeptEarly,      ///< overtook its data: applied when the data arrives
  };

  explicit KeyframeReassembly(ReassemblyOptions options = {}) : options_(options) {}

  /// A full keyframe of `agent` and the reference keyframe the agent named with it.
  void AddKeyframe(AgentId agent, KeyframeData keyframe, KeyframeId reference_kf, Clock::time_point now);
  /// A full map point: into its batch at once (with an update that overtook it applied).
  void AddMapPoint(AgentId agent, MapPointData point, Clock::time_point now, BatchSet* out);
  UpdateFate AddKeyframeUpdate(AgentId agent, const KeyframePoseUpdate& update, BatchSet* out);
  /// `segment`: the segment of the point's batch on the wire.
  UpdateFate AddMapPointUpdate(AgentId agent, const MapPointPositionUpdate& update, MapId segment, BatchSet* out);

  /// Moves held keyframes whose points all arrived, or that waited max_keyframe_hold, into
  /// `out` (the batch's reference keyframe becomes the one named with the keyframe). Returns
  /// per agent how many left without all their points.
  std::map<AgentId, int64_t> Release(Clock::time_point now, BatchSet* out);
  /// Drops everything held or remembered for `agent` (its slot was released).
  void Forget(AgentId agent) { agents_.erase(agent); }
  /// When the oldest held keyframe leaves even without its points; nullopt when none is held.
  std::optional<Clock::time_point> NextDeadline() const;
  size_t held() const;

 private:
  struct Held {
    KeyframeData data;
    KeyframeId reference_kf;
    Clock::time_point since;
  };
  struct SeenIds {
    std::unordered_set<uint64_t> ids;
    std::deque<std::pair<Clock::time_point, uint64_t>> order;
    uint64_t pruned_below = 0;  ///< counters below this count as seen
    void Note(uint64_t packed, Clock::time_point now, std::chrono::seconds window);
    bool Seen(uint64_t packed, uint64_t counter) const { return counter < pruned_below || ids.count(packed) > 0; }
  };
  struct Early {
    std::unordered_map<uint64_t, KeyframePoseUpdate> keyframes;
    std::unordered_map<uint64_t, MapPointPositionUpdate> points;
  };
  struct AgentStreams {
    std::deque<Held> held;
    SeenIds keyframes, points;
    Early early;
  };

  bool Complete(AgentId agent, const AgentStreams& s, const KeyframeData& kf) const;

  const ReassemblyOptions options_;
  std::map<AgentId, AgentStreams> agents_;
};

}  // namespace ccm::server
