// Agent-side bookkeeping of CCM-SLAM's optimistic acknowledgement scheme: the server lists
// the keyframes it processed inside its (BEST_EFFORT, never acked) messages; when the
// agent sees KF i acknowledged but KF i-1 (sent earlier) not, it resends i-1 in full.
// It is also the VO's AckSource: the local map lets an acknowledged keyframe go (N+B rule).
// No DDS and no clock of its own. Thread-safe: the comm thread updates it, the VO's mapping
// thread asks IsAcked(); one internal mutex, a leaf.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/vo/local_map_bound.h"

namespace ccm::agent {

class AckTracker final : public AckSource {
 public:
  using Clock = std::chrono::steady_clock;

  /// `resend_holdoff`: a KF is not resent again sooner than this after its last send, so a
  /// burst of acks (or a slow link) does not trigger a resend storm.
  explicit AckTracker(std::chrono::milliseconds resend_holdoff = std::chrono::milliseconds(1000))
      : holdoff_(resend_holdoff) {}

  void OnSent(KeyframeId id, Clock::time_point now);
  /// Registers acknowledgements; returns the KFs to resend now (ascending).
  std::vector<KeyframeId> OnAcked(const std::vector<KeyframeId>& acked, Clock::time_point now);
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

  /// Acknowledged ids remembered for IsAcked (far more than a local map's N + B keyframes).
  static constexpr std::size_t kRememberedAcks = 4096;

 private:
  struct Entry {
    Clock::time_point first_sent, last_sent;
    int timeouts = 0;  ///< timeout resends so far (backoff)
    bool acked = false;
  };
  mutable std::mutex mutex_;
  std::map<KeyframeId, Entry> entries_;  // ordered: the predecessor of i is the previous entry
  std::set<KeyframeId> acked_;           // newest kRememberedAcks acknowledged ids
  std::deque<float> latencies_ms_;       // newest kRememberedAcks send-to-ack times
  std::chrono::milliseconds holdoff_;
  std::uint64_t acked_count_ = 0;
  std::uint64_t resent_count_ = 0;
  std::uint64_t resent_gap_count_ = 0;
};

}  // namespace ccm::agent
