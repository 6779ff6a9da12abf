// Agent-side bookkeeping of CCM-SLAM's optimistic acknowledgement scheme: the server lists
// the keyframes it processed inside its (BEST_EFFORT, never acked) messages; when the
// agent sees KF i acknowledged but KF i-1 (sent earlier) not, it resends i-1 in full.
// Durable acks (docs/protocol.md "Epochs and persisted acks"): each ack comes with the
// server's epoch and its ack message number; a message's persisted_seq says which acks are
// in the server's map file. A keyframe is kept for resends until persisted; when a newer
// epoch appears (the server restarted), what it processed but had not saved is resent.
// It is also the VO's AckSource: the local map lets a persisted keyframe go (N+B rule).
// No DDS and no clock of its own. Thread-safe: the comm thread updates it, the VO's mapping
// thread asks IsAcked()/IsPersisted(); one internal mutex, a leaf.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/vo/local_map_bound.h"

namespace ccm::agent {

/// Where a server message stands in the server's life (conv::ServerAckStamp off the wire).
/// The default makes every ack final at once (a server without persistence; tests).
struct AckStamp {
  std::uint64_t epoch = 1;
  std::uint64_t ack_seq = 0;
  std::uint64_t persisted_seq = std::numeric_limits<std::uint64_t>::max();
};

class AckTracker final : public AckSource {
 public:
  using Clock = std::chrono::steady_clock;

  /// `resend_holdoff`: a KF is not resent again sooner than this after its last send, so a
  /// burst of acks (or a slow link) does not trigger a resend storm.
  explicit AckTracker(std::chrono::milliseconds resend_holdoff = std::chrono::milliseconds(1000))
      : holdoff_(resend_holdoff) {}

  void OnSent(KeyframeId id, Clock::time_point now);
  /// Registers one server message's acknowledgements; returns the KFs to resend now
  /// (ascending): by the gap rule, and on a newer epoch every KF processed but not
  /// persisted by the server before. A message of an older epoch than one seen is ignored,
  /// unless kStaleRunToAdopt of them in a row come from one older epoch and none from the
  /// newest: then the server restarted with its clock set back, and its epoch is adopted.
  std::vector<KeyframeId> OnAcked(const std::vector<KeyframeId>& acked, Clock::time_point now,
                                  const AckStamp& stamp = {});
  /// Unacknowledged KFs sent longer than `timeout` ago (e.g. the newest KFs when the server
  /// went silent): candidates for a resend. The wait doubles with every timeout resend of
  /// the same KF (up to 16x): on a slow lossy link the reliable stream is still delivering
  /// the first copy, and resending on a fixed timer turned the backlog into a resend storm
  /// (measured at 20% loss, 200 ms delay: 207 resends for 54 keyframes, nothing got through).
  /// `not_before`: the wait counts from here at the earliest (when the server was matched:
  /// keyframes written before sat in the DDS history, the server could not ack them).
  std::vector<KeyframeId> Overdue(std::chrono::milliseconds timeout, Clock::time_point now,
                                  Clock::time_point not_before = Clock::time_point::min());
  /// The local map may drop this KF without data loss. Stays true after the tracker
  /// stopped tracking the KF's resend state.
  bool IsAcked(KeyframeId id) const override;
  /// Acknowledged and in the map file of the server's current epoch.
  bool IsPersisted(KeyframeId id) const override;
  /// The KF left the agent for good (dropped unacknowledged): stop resending it.
  void Forget(KeyframeId id);

  /// Time from a keyframe's first send to its ack, over the newest kRememberedAcks acks.
  struct Latency {
    double median_ms = 0.0, p95_ms = 0.0, max_ms = 0.0;
    std::size_t count = 0;
  };
  Latency AckLatency() const;

  std::uint64_t acked_count() const;
  std::uint64_t resent_count() const;
  /// Of those, by the gap rule (the rest by the timeout rule).
  std::uint64_t resent_gap_count() const;
  std::size_t unacked_count() const;
  /// Keyframes whose resend state is kept: the unacknowledged, the acknowledged but not
  /// persisted, and one persisted successor per unacknowledged one (bounded by those).
  std::size_t tracked_count() const;
  /// What the durable acks did so far (one lock for all of it).
  struct DurableCounts {
    std::size_t unpersisted = 0;            ///< acknowledged, not persisted: needed if the server restarts now
    std::uint64_t persisted = 0;
    std::uint64_t server_restarts = 0;      ///< newer epochs seen after the first
    std::uint64_t resent_after_restart = 0;
    std::uint64_t stale_messages = 0;       ///< ignored: older than the newest epoch
  };
  DurableCounts durable_counts() const;

  static constexpr int kStaleRunToAdopt = 20;
  /// Acknowledged ids remembered for IsAcked (far more than a local map's N + B keyframes).
  static constexpr std::size_t kRememberedAcks = 4096;

 private:
  struct Entry {
    Clock::time_point first_sent, last_sent;
    int timeouts = 0;  ///< timeout resends so far (backoff)
    bool acked = false;
    bool persisted = false;
    std::uint64_t acked_seq = 0;  ///< number of the first message of this epoch that acked it
  };
  /// Moves entries acknowledged in a message numbered <= persisted_seq_ to persisted_.
  void MarkPersistedLocked();
  mutable std::mutex mutex_;
  std::map<KeyframeId, Entry> entries_;  // ordered: the predecessor of i is the previous entry
  std::set<KeyframeId> acked_;           // newest kRememberedAcks acknowledged ids
  std::set<KeyframeId> persisted_;       // newest kRememberedAcks persisted ids
  std::uint64_t epoch_ = 0;              // newest server epoch seen (0: none yet)
  std::uint64_t persisted_seq_ = 0;      // in epoch_
  std::uint64_t stale_run_epoch_ = 0;    // the older epoch of the current run of stale messages
  int stale_run_ = 0;
  DurableCounts durable_;  // .unpersisted is computed by durable_counts()
  std::deque<float> latencies_ms_;       // newest kRememberedAcks send-to-ack times
  std::chrono::milliseconds holdoff_;
  std::uint64_t acked_count_ = 0;
  std::uint64_t resent_count_ = 0;
  std::uint64_t resent_gap_count_ = 0;
};

}  // namespace ccm::agent
