// Agent-side bookkeeping of CCM-SLAM's optimistic acknowledgement scheme: the server lists
// the keyframes it processed inside its (BEST_EFFORT, never acked) messages; when the
// agent sees KF i acknowledged but KF i-1 (sent earlier) not, it resends i-1 in full.
// Pure logic, no DDS and no clock of its own: owned and called by one comm thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <vector>

#include "slam_core/common/ids.h"

namespace ccm::agent {

class AckTracker {
 public:
  using Clock = std::chrono::steady_clock;

  /// `resend_holdoff`: a KF is not resent again sooner than this after its last send, so a
  /// burst of acks (or a slow link) does not trigger a resend storm.
  explicit AckTracker(std::chrono::milliseconds resend_holdoff = std::chrono::milliseconds(1000))
      : holdoff_(resend_holdoff) {}

  void OnSent(KeyframeId id, Clock::time_point now);
  /// Registers acknowledgements; returns the KFs to resend now (ascending).
  std::vector<KeyframeId> OnAcked(const std::vector<KeyframeId>& acked, Clock::time_point now);
  /// Unacknowledged KFs sent longer than `timeout` ago whose successor was never acked
  /// either (e.g. the newest KFs when the server went silent): candidates for a resend.
  std::vector<KeyframeId> Overdue(std::chrono::milliseconds timeout, Clock::time_point now);
  /// The local map may drop this KF without data loss.
  bool IsAcked(KeyframeId id) const;
  void Forget(KeyframeId id) { entries_.erase(id); }

  std::uint64_t acked_count() const { return acked_count_; }
  std::uint64_t resent_count() const { return resent_count_; }
  std::size_t unacked_count() const;

 private:
  struct Entry {
    Clock::time_point last_sent;
    bool acked = false;
  };
  std::map<KeyframeId, Entry> entries_;  // ordered: the predecessor of i is the previous entry
  std::chrono::milliseconds holdoff_;
  std::uint64_t acked_count_ = 0;
  std::uint64_t resent_count_ = 0;
};

}  // namespace ccm::agent
