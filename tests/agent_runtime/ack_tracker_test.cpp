#include "agent_runtime/ack_tracker.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace ccm::agent {
namespace {

using Clock = AckTracker::Clock;
using std::chrono::milliseconds;

KeyframeId Kf(int i) { return KeyframeId::Make(1, i); }

TEST(AckTracker, ResendsPredecessorOfAckedKeyframe) {
  AckTracker t(milliseconds(100));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 5; ++i) t.OnSent(Kf(i), t0);
  // Server processed 1, 2 and 4: KF 3 was skipped (lost or still in flight).
  const auto resend = t.OnAcked({Kf(1), Kf(2), Kf(4)}, t0 + milliseconds(500));
  ASSERT_EQ(resend.size(), 1u);
  EXPECT_EQ(resend[0], Kf(3));
  EXPECT_EQ(t.resent_count(), 1u);
  EXPECT_EQ(t.resent_gap_count(), 1u);
  EXPECT_EQ(t.acked_count(), 3u);
  EXPECT_TRUE(t.IsAcked(Kf(4)));
  EXPECT_FALSE(t.IsAcked(Kf(3)));
  EXPECT_EQ(t.unacked_count(), 2u);  // 3 and 5 (5 has no acked successor: no resend)
}

TEST(AckTracker, HoldoffPreventsResendStorms) {
  AckTracker t(milliseconds(1000));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 3; ++i) t.OnSent(Kf(i), t0);
  EXPECT_TRUE(t.OnAcked({Kf(3)}, t0 + milliseconds(10)).empty());  // just sent: wait
  const auto later = t.OnAcked({Kf(3)}, t0 + milliseconds(1500));
  EXPECT_EQ(later, (std::vector<KeyframeId>{Kf(2)}));  // only the direct predecessor of an acked KF
  EXPECT_TRUE(t.OnAcked({}, t0 + milliseconds(1600)).empty());      // holdoff after the resend
}

TEST(AckTracker, DuplicateAndUnknownAcksAreIgnored) {
  AckTracker t;
  const auto t0 = Clock::now();
  t.OnSent(Kf(1), t0);
  t.OnAcked({Kf(1), Kf(1), Kf(99)}, t0);
  EXPECT_EQ(t.acked_count(), 1u);
  EXPECT_EQ(t.unacked_count(), 0u);
}

TEST(AckTracker, OverdueKeyframesAreResentOnceThenAfterTimeout) {
  AckTracker t;
  const auto t0 = Clock::now();
  t.OnSent(Kf(1), t0);
  t.OnSent(Kf(2), t0);
  EXPECT_TRUE(t.Overdue(milliseconds(5000), t0 + milliseconds(100)).empty());
  EXPECT_EQ(t.Overdue(milliseconds(5000), t0 + milliseconds(6000)).size(), 2u);
  EXPECT_TRUE(t.Overdue(milliseconds(5000), t0 + milliseconds(7000)).empty());
  EXPECT_EQ(t.resent_count(), 2u);
  EXPECT_EQ(t.resent_gap_count(), 0u);
}

TEST(AckTracker, TheTimeoutCountsFromTheServerMatchAtTheEarliest) {
  // Written while no server was matched: the keyframe waited in the DDS history, and the
  // server matched at t0 + 20 s has not had 5 s to ack it yet.
  AckTracker t;
  const auto t0 = Clock::now();
  t.OnSent(Kf(1), t0);
  const auto matched = t0 + std::chrono::seconds(20);
  EXPECT_TRUE(t.Overdue(milliseconds(5000), matched + milliseconds(1000), matched).empty());
  EXPECT_EQ(t.Overdue(milliseconds(5000), matched + milliseconds(5000), matched).size(), 1u);
}

TEST(AckTracker, StaysBoundedOverALongRun) {
  AckTracker t(milliseconds(0));
  auto now = Clock::now();
  for (int i = 1; i <= 10000; ++i) {
    t.OnSent(Kf(i), now);
    if (i % 10 == 0) {
      std::vector<KeyframeId> acked;
      for (int j = i - 9; j <= i; ++j) acked.push_back(Kf(j));
      t.OnAcked(acked, now);
    }
    now += milliseconds(100);
  }
  EXPECT_EQ(t.acked_count(), 10000u);
  EXPECT_EQ(t.unacked_count(), 0u);
  EXPECT_EQ(t.resent_count(), 0u);
}

}  // namespace
}  // namespace ccm::agent

namespace ccm::agent {
namespace {

TEST(AckTracker, AcknowledgedKeyframesStayAckedAfterTheirBookkeepingIsPruned) {
  // The old tracker answered false once an acked prefix was pruned: the local map would
  // then have counted a keyframe the server has as lost.
  AckTracker t(std::chrono::milliseconds(0));
  const auto t0 = AckTracker::Clock::now();
  for (int i = 1; i <= 5; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1), Kf(2), Kf(3)}, t0);
  EXPECT_EQ(t.unacked_count(), 2u);
  for (int i = 1; i <= 3; ++i) EXPECT_TRUE(t.IsAcked(Kf(i))) << i;
  EXPECT_FALSE(t.IsAcked(Kf(4)));
  const AckSource& as_source = t;
  EXPECT_TRUE(as_source.IsAcked(Kf(2)));
}

TEST(AckTracker, ForgottenKeyframesAreNotResent) {
  AckTracker t(std::chrono::milliseconds(0));
  const auto t0 = AckTracker::Clock::now();
  for (int i = 1; i <= 3; ++i) t.OnSent(Kf(i), t0);
  t.Forget(Kf(2));  // dropped from the agent's buffer unacknowledged
  // 1 is now the unacknowledged keyframe before an acknowledged one; 2 is never asked for.
  EXPECT_EQ(t.OnAcked({Kf(3)}, t0 + std::chrono::seconds(2)), (std::vector<KeyframeId>{Kf(1)}));
  EXPECT_EQ(t.Overdue(std::chrono::milliseconds(1), t0 + std::chrono::seconds(3)), (std::vector<KeyframeId>{Kf(1)}));
  EXPECT_EQ(t.unacked_count(), 1u);
}

TEST(AckTracker, TheMappingThreadMayAskWhileTheCommThreadAcks) {
  AckTracker t(std::chrono::milliseconds(0));
  const auto t0 = AckTracker::Clock::now();
  std::atomic<bool> done{false};
  std::atomic<int64_t> answers{0};
  std::thread reader([&] {
    while (!done) answers += t.IsAcked(Kf(7)) ? 1 : 0;
  });
  for (int i = 1; i <= 20000; ++i) {
    t.OnSent(Kf(i), t0);
    if (i % 5 == 0) t.OnAcked({Kf(i - 4), Kf(i - 3), Kf(i - 2), Kf(i - 1), Kf(i)}, t0);
  }
  done = true;
  reader.join();
  EXPECT_EQ(t.acked_count(), 20000u);
  EXPECT_FALSE(t.IsAcked(Kf(7))) << "only the newest acknowledgements are remembered";
  EXPECT_TRUE(t.IsAcked(Kf(20000)));
}

TEST(AckTracker, AckLatencyCountsFromTheFirstSendNotTheResend) {
  AckTracker t(milliseconds(100));
  const auto t0 = Clock::now();
  EXPECT_EQ(t.AckLatency().count, 0u);
  t.OnSent(Kf(1), t0);
  t.OnSent(Kf(2), t0 + milliseconds(100));
  t.OnSent(Kf(1), t0 + milliseconds(5000));  // a timeout resend
  t.OnAcked({Kf(1), Kf(2)}, t0 + milliseconds(6000));
  t.OnAcked({Kf(1)}, t0 + milliseconds(7000));  // a repeated ack is not a second sample
  const AckTracker::Latency l = t.AckLatency();
  EXPECT_EQ(l.count, 2u);
  EXPECT_NEAR(l.max_ms, 6000.0, 1.0);
  EXPECT_NEAR(l.median_ms, 6000.0, 1.0);  // upper median of {5900, 6000}
  t.OnSent(Kf(3), t0 + milliseconds(6000));
  t.OnAcked({Kf(3)}, t0 + milliseconds(6010));
  EXPECT_NEAR(t.AckLatency().median_ms, 5900.0, 1.0);
}

}  // namespace
}  // namespace ccm::agent

// ---- Durable acks: epochs and persisted acks (docs/protocol.md).
namespace ccm::agent {
namespace {

constexpr std::uint64_t kEpoch1 = 1000, kEpoch2 = 2000;

TEST(AckTracker, AKeyframeIsPersistedOnlyOnceASaveCoversItsAckMessage) {
  AckTracker t(milliseconds(0));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 4; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1), Kf(2)}, t0, {kEpoch1, 1, 0});  // ack message 1, nothing saved yet
  t.OnAcked({Kf(3)}, t0, {kEpoch1, 2, 0});
  EXPECT_TRUE(t.IsAcked(Kf(3)));
  EXPECT_FALSE(t.IsPersisted(Kf(1)));
  EXPECT_EQ(t.durable_counts().unpersisted, 3u);
  t.OnAcked({}, t0, {kEpoch1, 0, 1});  // a heartbeat: the map file covers message 1
  EXPECT_TRUE(t.IsPersisted(Kf(1)));
  EXPECT_TRUE(t.IsPersisted(Kf(2)));
  EXPECT_FALSE(t.IsPersisted(Kf(3)));
  EXPECT_EQ(t.durable_counts().persisted, 2u);
  EXPECT_EQ(t.durable_counts().unpersisted, 1u);
  const AckSource& as_source = t;
  EXPECT_TRUE(as_source.IsPersisted(Kf(2)));
  EXPECT_FALSE(as_source.IsPersisted(Kf(3)));
}

TEST(AckTracker, ARestartedServerGetsWhatItProcessedButHadNotSavedAndNothingElse) {
  AckTracker t(milliseconds(0));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 6; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1), Kf(2)}, t0, {kEpoch1, 1, 0});
  t.OnAcked({Kf(3), Kf(4)}, t0, {kEpoch1, 2, 1});  // saved through message 1
  // KF 5 was never acked, KF 6 is in flight. The server dies; a new start says hello.
  const auto resend = t.OnAcked({}, t0 + milliseconds(10), {kEpoch2, 0, 0});
  EXPECT_EQ(resend, (std::vector<KeyframeId>{Kf(3), Kf(4)})) << "processed, unsaved: gone with the old server";
  EXPECT_EQ(t.durable_counts().server_restarts, 1u);
  EXPECT_EQ(t.durable_counts().resent_after_restart, 2u);
  EXPECT_TRUE(t.IsPersisted(Kf(1)));
  EXPECT_FALSE(t.IsAcked(Kf(3)));
  EXPECT_EQ(t.unacked_count(), 4u);  // 3, 4 (resent) and 5, 6 (the timeout rule's)
  EXPECT_EQ(t.acked_count(), 2u);    // distinct keyframes acked: 1 and 2
  // The new server acks them under its own numbering and saves.
  t.OnAcked({Kf(3), Kf(4), Kf(5), Kf(6)}, t0 + milliseconds(20), {kEpoch2, 1, 1});
  for (int i = 1; i <= 6; ++i) EXPECT_TRUE(t.IsPersisted(Kf(i))) << i;
  EXPECT_EQ(t.acked_count(), 6u);
  EXPECT_EQ(t.unacked_count(), 0u);
  EXPECT_EQ(t.durable_counts().unpersisted, 0u);
}

TEST(AckTracker, MessagesOfAnOlderServerStartAreIgnored) {
  AckTracker t(milliseconds(0));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 3; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1)}, t0, {kEpoch2, 1, 1});
  EXPECT_TRUE(t.OnAcked({Kf(2)}, t0, {kEpoch1, 7, 7}).empty());
  EXPECT_FALSE(t.IsAcked(Kf(2))) << "an ack of a server that is gone says nothing about the current one";
  EXPECT_EQ(t.durable_counts().stale_messages, 1u);
  EXPECT_EQ(t.durable_counts().server_restarts, 0u);
}

TEST(AckTracker, ASaveNumberFromTheSameMessageMakesItsAcksFinal) {
  // A server without a map file: persisted_seq is the message's own number.
  AckTracker t(milliseconds(0));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 3; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1), Kf(2), Kf(3)}, t0, {kEpoch1, 5, 5});
  for (int i = 1; i <= 3; ++i) EXPECT_TRUE(t.IsPersisted(Kf(i))) << i;
  EXPECT_TRUE(t.OnAcked({}, t0, {kEpoch2, 0, 0}).empty()) << "nothing to resend after a restart";
}

}  // namespace
}  // namespace ccm::agent

namespace ccm::agent {
namespace {

TEST(AckTracker, AServerRestartedWithItsClockSetBackIsAdoptedAfterARunOfItsMessages) {
  // Epochs are start times: a ground station whose clock went back starts with a smaller
  // one. Ignoring it forever would leave every keyframe unacknowledged.
  AckTracker t(std::chrono::milliseconds(0));
  const auto t0 = Clock::now();
  for (int i = 1; i <= 3; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1), Kf(2)}, t0, {2000, 1, 0});
  std::vector<KeyframeId> resend;
  for (int i = 0; i < AckTracker::kStaleRunToAdopt; ++i) resend = t.OnAcked({Kf(3)}, t0, {500, 1, 0});
  EXPECT_EQ(resend, (std::vector<KeyframeId>{Kf(1), Kf(2)}));
  EXPECT_EQ(t.durable_counts().server_restarts, 1u);
  EXPECT_TRUE(t.IsAcked(Kf(3)));
  EXPECT_FALSE(t.IsAcked(Kf(1))) << "acked by the old start, not saved: resent";
  // One message of the newest epoch in between restarts the count.
  AckTracker u(std::chrono::milliseconds(0));
  u.OnSent(Kf(1), t0);
  u.OnAcked({}, t0, {2000, 0, 0});
  for (int i = 0; i < 3 * AckTracker::kStaleRunToAdopt; ++i) {
    u.OnAcked({}, t0, {i % (AckTracker::kStaleRunToAdopt - 1) == 0 ? 2000u : 500u, 0, 0});
  }
  EXPECT_EQ(u.durable_counts().server_restarts, 0u);
}

}  // namespace
}  // namespace ccm::agent

namespace ccm::agent {
namespace {

TEST(AckTracker, AKeyframeNeverAcknowledgedDoesNotPinEverythingSentAfterIt) {
  // Keyframe 1 is never acknowledged (the server keeps rejecting it); 2..5000 are acked and
  // saved. The tracker used to keep every persisted entry behind 1: 5000 entries after
  // 5000 keyframes. Only 1 and its successor (for the gap rule) are needed.
  AckTracker t(std::chrono::milliseconds(0));
  auto now = AckTracker::Clock::now();
  t.OnSent(Kf(1), now);
  for (int i = 2; i <= 5000; ++i) {
    t.OnSent(Kf(i), now);
    const auto resend = t.OnAcked({Kf(i)}, now, {1, static_cast<std::uint64_t>(i), static_cast<std::uint64_t>(i)});
    if (i == 2) {
      EXPECT_EQ(resend, (std::vector<KeyframeId>{Kf(1)}));
    }
    now += std::chrono::milliseconds(100);
  }
  EXPECT_EQ(t.unacked_count(), 1u);
  EXPECT_EQ(t.tracked_count(), 2u);
  EXPECT_TRUE(t.IsPersisted(Kf(5000)));
  EXPECT_FALSE(t.IsAcked(Kf(1)));
  // The gap rule still asks for 1 (its acknowledged successor was kept).
  EXPECT_EQ(t.OnAcked({}, now, {1, 5001, 5000}), (std::vector<KeyframeId>{Kf(1)}));
}

TEST(AckTracker, AcknowledgedButUnsavedKeyframesStayTrackedForARestart) {
  AckTracker t(std::chrono::milliseconds(0));
  const auto t0 = AckTracker::Clock::now();
  for (int i = 1; i <= 6; ++i) t.OnSent(Kf(i), t0);
  t.OnAcked({Kf(1), Kf(2), Kf(3)}, t0, {1, 1, 1});   // saved
  t.OnAcked({Kf(5), Kf(6)}, t0, {1, 2, 1});          // processed, not saved; 4 missing
  // 4 (unacked) and 5, 6 (not saved) are needed; 1-3 are not.
  EXPECT_EQ(t.tracked_count(), 3u);
  EXPECT_EQ(t.OnAcked({}, t0, {2, 1, 0}), (std::vector<KeyframeId>{Kf(5), Kf(6)}));
}

}  // namespace
}  // namespace ccm::agent
