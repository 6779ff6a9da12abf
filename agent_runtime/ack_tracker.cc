#include "agent_runtime/ack_tracker.h"

#include <algorithm>
#include <iterator>

namespace ccm::agent {

void AckTracker::OnSent(KeyframeId id, Clock::time_point now) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (acked_.count(id) || persisted_.count(id)) return;  // a resend of something the server already has
  const auto [it, fresh] = entries_.try_emplace(id);
  if (fresh) it->second.first_sent = now;
  it->second.last_sent = now;
}

std::vector<KeyframeId> AckTracker::OnAcked(const std::vector<KeyframeId>& acked, Clock::time_point now,
                                            const AckStamp& stamp) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stamp.epoch < epoch_) {  // from a server start before the newest one seen
    stale_run_ = stamp.epoch == stale_run_epoch_ ? stale_run_ + 1 : 1;
    stale_run_epoch_ = stamp.epoch;
    ++durable_.stale_messages;
    if (stale_run_ < kStaleRunToAdopt) return {};
  }
  if (stamp.epoch == epoch_) stale_run_ = 0;
  std::vector<KeyframeId> resend;
  if (stamp.epoch != epoch_) {
    stale_run_ = 0;
    // A server start: what the previous one processed but had not saved is gone with it.
    // Resend at once (the new server has nothing of it) and wait for this epoch's acks.
    if (epoch_ != 0) {
      ++durable_.server_restarts;
      for (auto& [id, entry] : entries_) {
        if (!entry.acked || entry.persisted) continue;
        entry.acked = false;
        entry.timeouts = 0;
        entry.last_sent = now;
        acked_.erase(id);
        --acked_count_;
        ++resent_count_;
        ++durable_.resent_after_restart;
        resend.push_back(id);
      }
    }
    epoch_ = stamp.epoch;
    persisted_seq_ = 0;
  }
  for (KeyframeId id : acked) {
    auto it = entries_.find(id);
    if (it == entries_.end() || it->second.acked) continue;  // unknown or duplicate ack
    it->second.acked = true;
    it->second.acked_seq = stamp.ack_seq;
    ++acked_count_;
    acked_.insert(id);
    latencies_ms_.push_back(std::chrono::duration<float, std::milli>(now - it->second.first_sent).count());
  }
  while (acked_.size() > kRememberedAcks) acked_.erase(acked_.begin());
  while (latencies_ms_.size() > kRememberedAcks) latencies_ms_.pop_front();
  persisted_seq_ = std::max(persisted_seq_, stamp.persisted_seq);
  // Walk in id order: an unacked entry directly followed by an acked one was skipped by
  // the server (lost or not yet processed): resend it unless it was sent very recently.
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    auto next = std::next(it);
    if (next == entries_.end()) break;
    if (!it->second.acked && next->second.acked && now - it->second.last_sent >= holdoff_) {
      it->second.last_sent = now;
      ++resent_count_;
      ++resent_gap_count_;
      resend.push_back(it->first);
    }
  }
  MarkPersistedLocked();
  std::sort(resend.begin(), resend.end());
  // A keyframe resent for the restart may also be a gap now (a zero holdoff): once.
  const auto dup = std::unique(resend.begin(), resend.end());
  resent_count_ -= static_cast<std::uint64_t>(resend.end() - dup);
  resent_gap_count_ -= static_cast<std::uint64_t>(resend.end() - dup);
  resend.erase(dup, resend.end());
  return resend;
}

void AckTracker::MarkPersistedLocked() {
  for (auto it = entries_.begin(); it != entries_.end();) {
    Entry& e = it->second;
    if (!e.acked || e.persisted || e.acked_seq > persisted_seq_) {
      ++it;
      continue;
    }
    e.persisted = true;
    persisted_.insert(it->first);
    ++durable_.persisted;
    ++it;
  }
  // A persisted entry is needed only as the acknowledged successor of an unacknowledged
  // one (the gap rule); IsAcked/IsPersisted answer from the sets. Keeping every persisted
  // entry behind a keyframe the server never acknowledges grew without bound.
  for (auto it = entries_.begin(); it != entries_.end();) {
    const bool after_unacked = it != entries_.begin() && !std::prev(it)->second.acked;
    it = it->second.persisted && !after_unacked ? entries_.erase(it) : std::next(it);
  }
  while (persisted_.size() > kRememberedAcks) persisted_.erase(persisted_.begin());
}

std::vector<KeyframeId> AckTracker::Overdue(std::chrono::milliseconds timeout, Clock::time_point now,
                                            Clock::time_point not_before) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<KeyframeId> out;
  for (auto& [id, entry] : entries_) {
    if (!entry.acked && now - std::max(entry.last_sent, not_before) >= timeout * (1 << std::min(entry.timeouts, 4))) {
      entry.last_sent = now;
      ++entry.timeouts;
      ++resent_count_;
      out.push_back(id);
    }
  }
  return out;
}

bool AckTracker::IsAcked(KeyframeId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return acked_.count(id) > 0;
}

bool AckTracker::IsPersisted(KeyframeId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return persisted_.count(id) > 0;
}

void AckTracker::Forget(KeyframeId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(id);
  if (it != entries_.end() && !it->second.acked) entries_.erase(it);
}

AckTracker::Latency AckTracker::AckLatency() const {
  std::vector<float> v;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    v.assign(latencies_ms_.begin(), latencies_ms_.end());
  }
  Latency l;
  l.count = v.size();
  if (v.empty()) return l;
  std::sort(v.begin(), v.end());
  l.median_ms = v[v.size() / 2];
  l.p95_ms = v[std::min(v.size() - 1, v.size() * 95 / 100)];
  l.max_ms = v.back();
  return l;
}

std::uint64_t AckTracker::acked_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return acked_count_;
}

std::uint64_t AckTracker::resent_gap_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return resent_gap_count_;
}

std::uint64_t AckTracker::resent_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return resent_count_;
}

AckTracker::DurableCounts AckTracker::durable_counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  DurableCounts c = durable_;
  for (const auto& [id, entry] : entries_) c.unpersisted += entry.acked && !entry.persisted ? 1 : 0;
  return c;
}

std::size_t AckTracker::tracked_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_.size();
}

std::size_t AckTracker::unacked_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t n = 0;
  for (const auto& [id, entry] : entries_) n += entry.acked ? 0 : 1;
  return n;
}

}  // namespace ccm::agent
