// Fuzz test of ServerComm's reassembly stage (server_runtime/keyframe_reassembly.h): what
// reaches it has passed conversion, so the hostile part is the stream itself: ids far ahead
// or far behind, resends, links to points that never come, updates for unknown ids, floods of
// early updates, time standing still or jumping past the hold and the seen window, three
// agents interleaved. Each input is one such message (or a release at a later time) into a
// reassembly that is replaced every 500 inputs. Checked against a record the test keeps:
// every keyframe leaves exactly once and in its agent's arrival order, into the batch of its
// agent and segment; none leaves incomplete before max_keyframe_hold nor stays once its
// points all arrived; an update for data that arrived is never kept as early; held() is what
// the record holds; at the end of each run everything has left. Inputs: CCM_FUZZ_INPUTS,
// 20,000 in the normal run (well under a second), 100,000 in deploy/run-sanitizer-tests.sh.
#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <iostream>
#include <map>
#include <random>
#include <set>

#include "server_runtime/keyframe_reassembly.h"
#include "tests/fuzz_inputs.h"

namespace ccm::server {
namespace {

using Clock = KeyframeReassembly::Clock;
using Fate = KeyframeReassembly::UpdateFate;

class ReassemblyRun {
 public:
  ReassemblyRun(std::mt19937_64* rng, ReassemblyOptions options) : rng_(*rng), options_(options), r_(options) {}

  // One hostile input.
  void Step() {
    const int kind = static_cast<int>(rng_() % 100);
    const AgentId agent = static_cast<AgentId>(1 + rng_() % 3);
    if (kind < 25) {
      AddKeyframe(agent);
    } else if (kind < 55) {
      AddPoint(agent);
    } else if (kind < 70) {
      KeyframePoseUpdate u;
      u.id = KeyframeId::Make(agent, Counter());
      u.segment = Segment(agent);
      u.pred_from_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(Uniform(), 0, 0));
      const Fate fate = r_.AddKeyframeUpdate(agent, u, &out_);
      if (arrived_kfs_[agent].count(u.id)) {
        EXPECT_NE(fate, Fate::kKeptEarly) << "an update for an arrived keyframe was kept as early";
      }
      if (fate == Fate::kAppliedToHeld) {
        EXPECT_TRUE(held_ids_[agent].count(u.id)) << "applied to a keyframe not held";
      }
      if (fate == Fate::kBatched) ++batched_updates_;
    } else if (kind < 80) {
      MapPointPositionUpdate u;
      u.id = MapPointId::Make(agent, Counter());
      const Fate fate = r_.AddMapPointUpdate(agent, u, Segment(agent), &out_);
      if (arrived_points_[agent].count(u.id)) {
        EXPECT_NE(fate, Fate::kKeptEarly) << "an update for an arrived point was kept as early";
      }
      EXPECT_NE(fate, Fate::kAppliedToHeld) << "point updates never change held keyframes";
      if (fate == Fate::kBatched) ++batched_updates_;
    } else {
      // Time: standing still, a little, past the hold, or (rarely) past the seen window.
      const int jump = static_cast<int>(rng_() % 20);
      now_ += jump < 5 ? Clock::duration::zero()
              : jump < 17 ? std::chrono::milliseconds(rng_() % 400)
              : jump < 19 ? options_.max_keyframe_hold + std::chrono::milliseconds(1)
                          : std::chrono::duration_cast<Clock::duration>(options_.seen_window) + std::chrono::seconds(1);
      Release();
    }
  }

  /// Everything must leave once the hold has passed.
  void Finish() {
    now_ += options_.max_keyframe_hold + std::chrono::milliseconds(1);
    Release();
    EXPECT_EQ(r_.held(), 0u);
    for (const auto& [agent, q] : queue_) EXPECT_TRUE(q.empty()) << "agent " << agent << " keeps keyframes";
  }

  int64_t released = 0, released_incomplete = 0, resends = 0, batched_updates_ = 0;

 private:
  struct Entry {
    KeyframeId id;
    Clock::time_point since;
    std::vector<MapPointId> own_links;
  };

  double Uniform() { return std::uniform_real_distribution<double>(-1, 1)(rng_); }
  // Mostly a small window of counters (so ids meet again), sometimes far ahead or 1.
  uint64_t Counter() {
    const int roll = static_cast<int>(rng_() % 20);
    if (roll == 0) return MapPointId::kCounterMask;
    if (roll == 1) return 1;
    if (roll == 2) return 1 + rng_() % (uint64_t{1} << 40);
    return base_ + rng_() % 64;
  }
  MapId Segment(AgentId agent) { return MapId::Make(agent, 1 + rng_() % 3); }

  void AddKeyframe(AgentId agent) {
    KeyframeData kf;
    // A resend of a keyframe still held, or a new one.
    auto& held = held_ids_[agent];
    kf.id = !held.empty() && rng_() % 4 == 0 ? *std::next(held.begin(), rng_() % held.size())
                                             : KeyframeId::Make(agent, Counter());
    kf.segment = Segment(agent);
    const int links = static_cast<int>(rng_() % 6);
    std::vector<MapPointId> own;
    for (int i = 0; i < links; ++i) {
      // Own points (some never sent), or another agent's (shared by the server: never awaited).
      const AgentId owner = rng_() % 4 == 0 ? static_cast<AgentId>(1 + rng_() % 3) : agent;
      const MapPointId mp = MapPointId::Make(owner, Counter());
      kf.point_links.emplace_back(i, mp);
      if (owner == agent) own.push_back(mp);
    }
    arrived_kfs_[agent].insert(kf.id);
    if (held.count(kf.id)) {
      ++resends;
      for (Entry& e : queue_[agent]) {
        if (e.id == kf.id) e.own_links = own;  // the newer copy replaces it, in its place
      }
    } else {
      held.insert(kf.id);
      queue_[agent].push_back({kf.id, now_, own});
    }
    r_.AddKeyframe(agent, std::move(kf), KeyframeId::Make(agent, 1), now_);
  }

  void AddPoint(AgentId agent) {
    MapPointData p;
    p.id = MapPointId::Make(agent, Counter());
    p.segment = Segment(agent);
    arrived_points_[agent].insert(p.id);
    point_times_[agent].emplace_back(now_, p.id.counter());
    const MapId segment = p.segment;
    const MapPointId id = p.id;
    r_.AddMapPoint(agent, std::move(p), now_, &out_);
    bool found = false;
    for (const AgentBatch& b : Peek()) {
      if (b.agent != agent || b.segment != segment) continue;
      for (const MapPointData& q : b.map_points) found |= q.id == id;
    }
    EXPECT_TRUE(found) << "a map point did not go into its agent's and segment's batch at once";
  }

  // The batches so far, kept for Release's check (BatchSet only hands them out with Take).
  const std::vector<AgentBatch>& Peek() {
    for (AgentBatch& b : out_.Take()) taken_.push_back(std::move(b));
    return taken_;
  }

  bool AllArrived(AgentId agent, const Entry& e) {
    for (const MapPointId mp : e.own_links) {
      if (!arrived_points_[agent].count(mp)) return false;
    }
    return true;
  }

  // Ids older than the oldest one forgotten (seen_window) count as arrived: no point with a
  // counter from this floor up does (the reassembly forgets no later than this record).
  uint64_t ForgottenFloor(AgentId agent) {
    uint64_t floor = 0;
    for (const auto& [t, counter] : point_times_[agent]) {
      if (now_ - t > options_.seen_window) floor = std::max(floor, counter + 1);
    }
    return floor;
  }
  bool MayCountAsArrived(AgentId agent, const Entry& e) {
    const uint64_t floor = ForgottenFloor(agent);
    for (const MapPointId mp : e.own_links) {
      if (!arrived_points_[agent].count(mp) && mp.counter() >= floor) return false;
    }
    return true;
  }

  void Release() {
    const auto incomplete = r_.Release(now_, &out_);
    for (const auto& [agent, n] : incomplete) released_incomplete += n;
    Peek();
    // Batches come out ordered by (agent, segment), so an agent's keyframes of several
    // segments interleave: what left must be a prefix of its arrival order, and each batch
    // must keep that order.
    std::map<AgentId, std::set<KeyframeId>> left;
    for (const AgentBatch& b : taken_) {
      int64_t last_position = -1;
      for (const KeyframeData& kf : b.keyframes) {
        EXPECT_EQ(kf.id.agent(), b.agent) << "a keyframe in another agent's batch";
        EXPECT_EQ(kf.segment, b.segment) << "a keyframe in another segment's batch";
        const auto& q = queue_[b.agent];
        int64_t position = -1;
        for (size_t i = 0; i < q.size() && position < 0; ++i) {
          if (q[i].id == kf.id) position = static_cast<int64_t>(i);
        }
        ASSERT_GE(position, 0) << "released a keyframe that is not held (twice, or never added)";
        EXPECT_GT(position, last_position) << "a batch holds an agent's keyframes out of arrival order";
        last_position = position;
        EXPECT_TRUE(left[b.agent].insert(kf.id).second) << "released twice in one cycle";
      }
    }
    taken_.clear();
    for (auto& [agent, ids] : left) {
      auto& q = queue_[agent];
      for (size_t i = 0; i < ids.size(); ++i) {
        ASSERT_TRUE(ids.count(q.front().id)) << "agent " << agent << "'s keyframes left out of arrival order";
        if (!MayCountAsArrived(agent, q.front())) {
          EXPECT_GE(now_ - q.front().since, options_.max_keyframe_hold) << "left without its points before the hold";
        }
        held_ids_[agent].erase(q.front().id);
        q.pop_front();
        ++released;
      }
    }
    size_t held = 0;
    for (const auto& [agent, q] : queue_) {
      held += q.size();
      if (q.empty()) continue;
      EXPECT_LT(now_ - q.front().since, options_.max_keyframe_hold) << "held past the hold";
      EXPECT_FALSE(AllArrived(agent, q.front())) << "held although all its points arrived";
    }
    EXPECT_EQ(r_.held(), held);
  }

  std::mt19937_64& rng_;
  const ReassemblyOptions options_;
  KeyframeReassembly r_;
  BatchSet out_;
  std::vector<AgentBatch> taken_;
  Clock::time_point now_ = Clock::now();
  const uint64_t base_ = 1000;
  std::map<AgentId, std::deque<Entry>> queue_;
  std::map<AgentId, std::set<KeyframeId>> held_ids_, arrived_kfs_;
  std::map<AgentId, std::set<MapPointId>> arrived_points_;
  std::map<AgentId, std::vector<std::pair<Clock::time_point, uint64_t>>> point_times_;
};

TEST(KeyframeReassemblyFuzz, HostileStreamsKeepEveryRuleAndEveryKeyframeLeavesOnce) {
  const int total = testing::FuzzInputs(20000);
  constexpr int kPerRun = 500;
  std::mt19937_64 rng(20261128);
  ReassemblyOptions options;
  options.max_early_updates = 64;  // small, so floods of early updates clear the table often
  int64_t released = 0, incomplete = 0, resends = 0, updates = 0;
  int runs = 0;
  for (int done = 0; done < total; done += kPerRun, ++runs) {
    ReassemblyRun run(&rng, options);
    for (int i = 0; i < std::min(kPerRun, total - done); ++i) {
      run.Step();
      if (::testing::Test::HasFatalFailure()) return;
    }
    run.Finish();
    released += run.released;
    incomplete += run.released_incomplete;
    resends += run.resends;
    updates += run.batched_updates_;
    if (::testing::Test::HasFailure()) break;  // the first run that fails tells enough
  }
  std::cout << total << " inputs in " << runs << " runs: " << released << " keyframes released (" << incomplete
            << " after the hold without all their points), " << resends << " resends of held keyframes, " << updates
            << " updates batched\n";
  EXPECT_GT(released, total / 20);
  EXPECT_GT(incomplete, 0);
  EXPECT_GT(released, incomplete) << "some keyframes should complete";
  EXPECT_GT(resends, 0);
}

}  // namespace
}  // namespace ccm::server
