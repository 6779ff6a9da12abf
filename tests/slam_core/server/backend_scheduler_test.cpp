// BackendScheduler on its own: admission limits, one handler per agent at a time, the order
// of optimization jobs (global BA before redundancy, the per-map pause), aborting a running
// global BA, idleness and Stop/Resume. No map work: batches carry one point update each.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <thread>

#include "slam_core/server/backend_scheduler.h"
#include "slam_core/server/map_stack.h"
#include "slam_core/server/registration.h"

namespace ccm {
namespace {

using std::chrono::milliseconds;

BackendScheduler::Limits SmallLimits() {
  BackendScheduler::Limits l;
  l.max_agents = 2;
  l.max_batches_per_agent = 3;
  l.max_bytes_per_agent = size_t{1} << 20;
  l.max_segments_per_agent = 2;
  return l;
}

// A non-empty batch of `agent` in segment `segment` with `updates` point updates.
AgentBatch Batch(AgentId agent, uint64_t segment = 1, int updates = 1) {
  AgentBatch b;
  b.agent = agent;
  b.segment = MapId::Make(agent, segment);
  for (int i = 0; i < updates; ++i) b.map_point_updates.push_back({MapPointId::Make(agent, i + 1), KeyframeId(), Eigen::Vector3d::Zero()});
  return b;
}

class SchedulerTest : public ::testing::Test {
 protected:
  BackendScheduler::Admission Admit(AgentBatch b, bool* first = nullptr) {
    bool f = false;
    const AgentId agent = b.agent;
    const auto r = scheduler_.Admit(
        std::move(b),
        [&] {
          ++registrations_made_;
          return std::make_unique<AgentRegistration>(agent, &stack_, RegistrationOptions{});
        },
        &f);
    if (first) *first = f;
    return r;
  }
  MapStack stack_{MapOptions{}};
  BackendScheduler scheduler_{SmallLimits()};
  int registrations_made_ = 0;
};

using Admission = BackendScheduler::Admission;

TEST_F(SchedulerTest, AdmissionRefusesBeyondEachLimitAndCreatesOneRegistrationPerAgent) {
  bool first = false;
  EXPECT_EQ(Admit(Batch(1), &first), Admission::kQueued);
  EXPECT_TRUE(first);
  EXPECT_EQ(Admit(Batch(1), &first), Admission::kQueued);
  EXPECT_FALSE(first) << "only the agent's first batch starts a handler";
  EXPECT_EQ(Admit(Batch(1)), Admission::kQueued);
  EXPECT_EQ(Admit(Batch(1)), Admission::kQueueFull) << "3 batches waiting";
  EXPECT_EQ(Admit(Batch(2)), Admission::kQueued);
  EXPECT_EQ(Admit(Batch(3)), Admission::kAgentRefused) << "max_agents 2";
  EXPECT_EQ(registrations_made_, 2);
  EXPECT_EQ(scheduler_.Agents(), (std::vector<AgentId>{1, 2}));

  // Segments: agent 2 has segment 1; a second is fine, a third is refused.
  EXPECT_EQ(Admit(Batch(2, 2)), Admission::kQueued);
  EXPECT_EQ(Admit(Batch(2, 3)), Admission::kSegments);
  const QueueDepths d = scheduler_.Depths();
  EXPECT_EQ(d.agent_batches.at(1), 3u);
  EXPECT_EQ(d.agent_batches.at(2), 2u);
}

TEST_F(SchedulerTest, AnAgentWhoseFirstBatchIsRefusedStartsItsHandlerWithItsNextBatch) {
  // Three segments in the first batch: more than max_segments_per_agent (2).
  AgentBatch three = Batch(1, 1);
  three.map_point_updates.push_back({MapPointId::Make(1, 7), KeyframeId(), Eigen::Vector3d::Zero()});
  three.keyframe_updates.push_back({});
  three.keyframe_updates.back().segment = MapId::Make(1, 2);
  three.keyframe_updates.push_back({});
  three.keyframe_updates.back().segment = MapId::Make(1, 3);
  bool first = true;
  EXPECT_EQ(Admit(std::move(three), &first), Admission::kSegments);
  EXPECT_FALSE(first);
  EXPECT_TRUE(scheduler_.Agents().empty()) << "a refused first batch takes no agent slot";
  EXPECT_EQ(Admit(Batch(2)), Admission::kQueued);
  EXPECT_EQ(Admit(Batch(3)), Admission::kQueued) << "max_agents 2: agent 1 holds none";
  EXPECT_EQ(Admit(Batch(1), &first), Admission::kAgentRefused);
}

TEST_F(SchedulerTest, AnAgentRefusedFirstThenAdmittedGetsItsHandler) {
  AgentBatch three = Batch(1, 1);
  for (uint64_t s : {2, 3}) {
    three.keyframe_updates.push_back({});
    three.keyframe_updates.back().segment = MapId::Make(1, s);
  }
  bool first = true;
  ASSERT_EQ(Admit(std::move(three), &first), Admission::kSegments);
  EXPECT_EQ(Admit(Batch(1), &first), Admission::kQueued);
  EXPECT_TRUE(first) << "the first admitted batch starts the agent's handler";
  EXPECT_TRUE(scheduler_.TakeBatch(1, milliseconds(0)).has_value());
}

TEST_F(SchedulerTest, ABatchOverTheByteBoundStillEntersAnEmptyQueue) {
  const AgentBatch big = Batch(1, 1, 60000);
  ASSERT_GT(ApproxBatchBytes(big), SmallLimits().max_bytes_per_agent);
  EXPECT_EQ(Admit(big), Admission::kQueued) << "an agent is never starved by one large batch";
  EXPECT_EQ(Admit(Batch(1)), Admission::kQueueBytes);
  EXPECT_EQ(scheduler_.Depths().agent_bytes.at(1), ApproxBatchBytes(big));
  ASSERT_TRUE(scheduler_.TakeBatch(1, milliseconds(0)));
  scheduler_.BatchDone(1);
  EXPECT_EQ(scheduler_.Depths().agent_bytes.at(1), 0u);
  EXPECT_EQ(Admit(Batch(1)), Admission::kQueued);
}

TEST_F(SchedulerTest, OneHandlerPerAgentAtATimeInSubmissionOrder) {
  AgentBatch a = Batch(1), b = Batch(1);
  a.stamp_ns = 1;
  b.stamp_ns = 2;
  Admit(a);
  Admit(b);
  Admit(Batch(2));
  auto first = scheduler_.TakeBatch(1, milliseconds(0));
  ASSERT_TRUE(first);
  EXPECT_EQ(first->batch.stamp_ns, 1);
  ASSERT_NE(first->registration, nullptr);
  EXPECT_EQ(first->registration->agent(), 1);
  EXPECT_FALSE(scheduler_.TakeBatch(1, milliseconds(20))) << "agent 1 is being handled";
  EXPECT_TRUE(scheduler_.TakeBatch(2, milliseconds(0))) << "other agents are not held up";
  scheduler_.BatchDone(1);
  const auto second = scheduler_.TakeBatch(1, milliseconds(0));
  ASSERT_TRUE(second);
  EXPECT_EQ(second->batch.stamp_ns, 2);
  EXPECT_EQ(second->registration, first->registration);
}

// Registration lag (GET /metrics): the age of the oldest batch not yet done, whether it
// waits or is being registered; 0 once the queue is empty.
TEST_F(SchedulerTest, RegistrationLagIsTheAgeOfTheOldestBatchNotYetDone) {
  Admit(Batch(1));
  std::this_thread::sleep_for(milliseconds(30));
  Admit(Batch(1));
  double lag = scheduler_.Depths().agent_lag_s.at(1);
  EXPECT_GE(lag, 0.03);
  ASSERT_TRUE(scheduler_.TakeBatch(1, milliseconds(0)));
  EXPECT_GE(scheduler_.Depths().agent_lag_s.at(1), lag) << "the batch in process still counts";
  scheduler_.BatchDone(1);
  lag = scheduler_.Depths().agent_lag_s.at(1);
  EXPECT_LT(lag, 0.03) << "now the second batch, admitted 30 ms later, is the oldest";
  ASSERT_TRUE(scheduler_.TakeBatch(1, milliseconds(0)));
  scheduler_.BatchDone(1);
  EXPECT_EQ(scheduler_.Depths().agent_lag_s.at(1), 0.0);
}

TEST_F(SchedulerTest, IdleOnlyWhenNothingIsQueuedOrRunning) {
  EXPECT_TRUE(scheduler_.Idle());
  Admit(Batch(1));
  EXPECT_FALSE(scheduler_.Idle());
  ASSERT_TRUE(scheduler_.TakeBatch(1, milliseconds(0)));
  EXPECT_FALSE(scheduler_.Idle()) << "taken, not done";
  scheduler_.QueueForPlaceRecognition({KeyframeId::Make(1, 1)});
  scheduler_.BatchDone(1);
  EXPECT_FALSE(scheduler_.Idle()) << "a keyframe waits for place recognition";
  ASSERT_EQ(scheduler_.TakeKeyframe(milliseconds(0)), KeyframeId::Make(1, 1));
  EXPECT_EQ(scheduler_.Depths().place_recognition, 1u) << "running counts";
  scheduler_.KeyframeDone();
  EXPECT_TRUE(scheduler_.Idle());
  scheduler_.EarnRedundancySteps(1);
  EXPECT_FALSE(scheduler_.Idle()) << "an earned redundancy step is work";
}

TEST_F(SchedulerTest, WaitUntilIdleReturnsOnceAnotherThreadFinishes) {
  Admit(Batch(1));
  auto waiter = std::async(std::launch::async, [&] { scheduler_.WaitUntilIdle(); });
  EXPECT_EQ(waiter.wait_for(milliseconds(50)), std::future_status::timeout);
  ASSERT_TRUE(scheduler_.TakeBatch(1, milliseconds(0)));
  scheduler_.BatchDone(1);
  EXPECT_EQ(waiter.wait_for(std::chrono::seconds(5)), std::future_status::ready);
}

TEST_F(SchedulerTest, GlobalBaComesBeforeRedundancyAndWaitsOutItsMapsPause) {
  const MapId m = MapId::Make(0, 1);
  scheduler_.EarnRedundancySteps(1);
  scheduler_.RequestGlobalBa(m);
  auto job = scheduler_.TakeOptimizationJob(milliseconds(0), true);
  ASSERT_TRUE(job);
  EXPECT_EQ(job->global_ba, m);
  EXPECT_TRUE(scheduler_.Depths().global_ba_running);
  scheduler_.GlobalBaDone(m, /*retry=*/false, std::chrono::seconds(60));
  scheduler_.OptimizationDone();

  scheduler_.RequestGlobalBa(m);
  job = scheduler_.TakeOptimizationJob(milliseconds(0), true);
  ASSERT_TRUE(job);
  EXPECT_FALSE(job->global_ba.valid()) << "the map is paused: the redundancy step goes first";
  scheduler_.OptimizationDone();
  EXPECT_FALSE(scheduler_.TakeOptimizationJob(milliseconds(20), true)) << "paused for 60 s";
  job = scheduler_.TakeOptimizationJob(milliseconds(0), /*respect_pause=*/false);
  ASSERT_TRUE(job) << "deterministic runs ignore the pause";
  EXPECT_EQ(job->global_ba, m);
}

TEST_F(SchedulerTest, ADetectionAbortsOnlyARunningGlobalBaOfItsMaps) {
  const MapId m1 = MapId::Make(0, 1), m2 = MapId::Make(0, 2), m3 = MapId::Make(0, 3);
  scheduler_.RequestGlobalBa(m1);
  scheduler_.RequestGlobalBa(m3);
  ASSERT_EQ(scheduler_.TakeOptimizationJob(milliseconds(0), true)->global_ba, m1);
  scheduler_.HoldGlobalBaOf(m2, m3);
  EXPECT_FALSE(scheduler_.abort_flag()->load()) << "m1 is not involved";
  scheduler_.ReleaseGlobalBaHold();
  scheduler_.HoldGlobalBaOf(m2, m1);
  EXPECT_TRUE(scheduler_.abort_flag()->load());
  scheduler_.ReleaseGlobalBaHold();
  // Aborted: queued again; a fused-away map's request is forgotten.
  scheduler_.GlobalBaDone(m1, /*retry=*/true, {});
  scheduler_.OptimizationDone();
  scheduler_.ForgetGlobalBa(m3);
  EXPECT_EQ(scheduler_.Depths().global_ba_pending, 1u);
  ASSERT_EQ(scheduler_.TakeOptimizationJob(milliseconds(0), true)->global_ba, m1);
  EXPECT_FALSE(scheduler_.abort_flag()->load()) << "a new run starts unaborted";
}

TEST_F(SchedulerTest, NoGlobalBaOfAMapStartsWhileADetectionIsAppliedToIt) {
  // A loop solves its pose graph with the map unlocked and half corrected: a global BA
  // started then would optimize (and drop as outliers) the loop's own observations.
  const MapId m1 = MapId::Make(0, 1), m2 = MapId::Make(0, 2);
  scheduler_.HoldGlobalBaOf(m1, m1);
  scheduler_.RequestGlobalBa(m1);
  scheduler_.RequestGlobalBa(m2);
  auto job = scheduler_.TakeOptimizationJob(milliseconds(0), true);
  ASSERT_TRUE(job);
  EXPECT_EQ(job->global_ba, m2) << "another map's global BA may run";
  scheduler_.GlobalBaDone(m2, false, {});
  scheduler_.OptimizationDone();
  EXPECT_FALSE(scheduler_.TakeOptimizationJob(milliseconds(20), false)) << "m1 is held";
  // A waiting optimization thread wakes when the hold ends.
  auto waiting = std::async(std::launch::async, [&] { return scheduler_.TakeOptimizationJob(std::chrono::seconds(30), false); });
  std::this_thread::sleep_for(milliseconds(20));
  scheduler_.ReleaseGlobalBaHold();
  ASSERT_EQ(waiting.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  job = waiting.get();
  ASSERT_TRUE(job);
  EXPECT_EQ(job->global_ba, m1);
}

TEST(SchedulerSlots, AnIdleAgentsSlotGoesToANewAgentItsHandlerEndsAndItCanReturn) {
  MapStack stack{MapOptions{}};
  BackendScheduler::Limits limits = SmallLimits();
  limits.max_agents = 1;
  limits.release_idle_after = milliseconds(50);
  BackendScheduler scheduler(limits);
  auto admit = [&](AgentBatch b, bool* first) {
    const AgentId agent = b.agent;
    return scheduler.Admit(std::move(b), [&] { return std::make_unique<AgentRegistration>(agent, &stack, RegistrationOptions{}); },
                           first);
  };
  auto drain = [&](AgentId agent) {
    ASSERT_TRUE(scheduler.TakeBatch(agent, milliseconds(0)));
    scheduler.BatchDone(agent);
  };
  bool first = false;
  ASSERT_EQ(admit(Batch(1, 1), &first), Admission::kQueued);
  EXPECT_TRUE(first);
  drain(1);
  EXPECT_EQ(admit(Batch(2), &first), Admission::kAgentRefused) << "agent 1 was heard from just now";
  // Agent 1's handler waits for work when the slot goes: it wakes and is told to end.
  auto waiting = std::async(std::launch::async, [&] {
    bool released = false;
    const bool got = scheduler.TakeBatch(1, std::chrono::seconds(30), &released).has_value();
    return !got && released;
  });
  std::this_thread::sleep_for(milliseconds(80));
  ASSERT_EQ(admit(Batch(2), &first), Admission::kQueued) << "agent 1 has been idle longer than 50 ms";
  EXPECT_TRUE(first);
  EXPECT_EQ(scheduler.slots_released(), 1);
  ASSERT_EQ(waiting.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  EXPECT_TRUE(waiting.get()) << "agent 1's handler stage ends";
  EXPECT_EQ(scheduler.Agents(), (std::vector<AgentId>{1, 2})) << "a released agent is still known";

  // A busy or non-empty queue is never released.
  EXPECT_EQ(admit(Batch(1, 1), &first), Admission::kAgentRefused);
  std::this_thread::sleep_for(milliseconds(80));
  EXPECT_EQ(admit(Batch(1, 1), &first), Admission::kAgentRefused) << "agent 2's batch is still queued";
  drain(2);
  std::this_thread::sleep_for(milliseconds(80));
  // Agent 1 returns: a new slot and a new handler; its segment budget (2) was kept.
  ASSERT_EQ(admit(Batch(1, 2), &first), Admission::kQueued);
  EXPECT_TRUE(first) << "its old handler ended, so a new one is needed";
  EXPECT_EQ(scheduler.slots_released(), 2);
  drain(1);
  EXPECT_EQ(admit(Batch(1, 3), &first), Admission::kSegments) << "segments 1, 2 and 3 are more than 2";
}

TEST(SchedulerSlots, ZeroNeverReleasesASlot) {
  MapStack stack{MapOptions{}};
  BackendScheduler::Limits limits = SmallLimits();
  limits.max_agents = 1;
  BackendScheduler scheduler(limits);
  bool first = false;
  auto make = [&] { return std::make_unique<AgentRegistration>(1, &stack, RegistrationOptions{}); };
  ASSERT_EQ(scheduler.Admit(Batch(1), make, &first), Admission::kQueued);
  ASSERT_TRUE(scheduler.TakeBatch(1, milliseconds(0)));
  scheduler.BatchDone(1);
  std::this_thread::sleep_for(milliseconds(30));
  EXPECT_EQ(scheduler.Admit(Batch(2), make, &first), Admission::kAgentRefused);
  EXPECT_EQ(scheduler.slots_released(), 0);
}

TEST_F(SchedulerTest, StopWakesWaitingStagesUntilResume) {
  auto waiting = std::async(std::launch::async, [&] { return scheduler_.TakeKeyframe(std::chrono::seconds(30)); });
  std::this_thread::sleep_for(milliseconds(20));
  const auto t0 = std::chrono::steady_clock::now();
  scheduler_.Stop();
  ASSERT_EQ(waiting.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  EXPECT_FALSE(waiting.get());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
  EXPECT_TRUE(scheduler_.abort_flag()->load()) << "a running global BA stops too";

  scheduler_.QueueForPlaceRecognition({KeyframeId::Make(1, 1)});
  EXPECT_FALSE(scheduler_.TakeKeyframe(milliseconds(0))) << "stopped";
  // A global BA that was aborted by the stop is not queued again.
  scheduler_.GlobalBaDone(MapId::Make(0, 1), /*retry=*/true, {});
  EXPECT_EQ(scheduler_.Depths().global_ba_pending, 0u);
  scheduler_.Resume();
  EXPECT_EQ(scheduler_.TakeKeyframe(milliseconds(0)), KeyframeId::Make(1, 1));
}

}  // namespace
}  // namespace ccm
