#include <gtest/gtest.h>

#include "slam_core/vo/local_map_bound.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm {
namespace {

// Keyframes of agent 1 in a chain, each sharing points with its neighbour, as the VO makes them.
struct Chain {
  testing::MapBuilder builder{200};
  std::vector<KeyframeId> ids;
  KeyframeId Add(LocalMapBound* bound) {
    const KeyframeId id = builder.AddKeyframe(static_cast<double>(ids.size()));
    if (!ids.empty()) builder.AddSharedPoints({ids.back(), id}, 20);
    builder.map().UpdateConnections(id);
    bound->OnKeyframeInserted(id);
    ids.push_back(id);
    return id;
  }
};

class SetAck final : public AckSource {
 public:
  std::set<KeyframeId> acked;
  bool IsAcked(KeyframeId kf) const override { return acked.count(kf) > 0; }
};

// Acked (processed) and persisted (saved by the server) as two sets.
class DurableAck final : public AckSource {
 public:
  std::set<KeyframeId> acked, persisted;
  bool IsAcked(KeyframeId kf) const override { return acked.count(kf) > 0; }
  bool IsPersisted(KeyframeId kf) const override { return persisted.count(kf) > 0; }
};

TEST(LocalMapBound, ProcessedButUnsavedKeyframesStayUntilPersistedAndGoBeforeUnackedOnes) {
  Chain chain;
  LocalMapBound bound(1, {5, 5});
  DurableAck acks;
  for (int i = 0; i < 10; ++i) bound.Trim(&chain.builder.map(), chain.Add(&bound), acks);
  // 0-3 processed, 4 not, nothing saved: all 10 stay (N + B).
  for (int i = 0; i < 4; ++i) acks.acked.insert(chain.ids[i]);
  bound.Trim(&chain.builder.map(), chain.ids.back(), acks);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 10u) << "a restarted server may need them";
  // Two more keyframes: over N + B the oldest processed ones go first, counted apart.
  for (int i = 0; i < 2; ++i) bound.Trim(&chain.builder.map(), chain.Add(&bound), acks);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 10u);
  EXPECT_EQ(bound.stats().removed_unpersisted, 2);
  EXPECT_EQ(bound.stats().removed_lost, 0);
  EXPECT_EQ(chain.builder.map().keyframe(chain.ids[0]), nullptr);
  EXPECT_NE(chain.builder.map().keyframe(chain.ids[4]), nullptr) << "the unacked one outlives processed ones";
  // A save covers 2 and 3: they leave as the server's for good.
  acks.persisted = {chain.ids[2], chain.ids[3]};
  bound.Trim(&chain.builder.map(), chain.ids.back(), acks);
  EXPECT_EQ(bound.stats().removed_acked, 2);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 8u);
}

TEST(LocalMapBound, OwnKeyframesTheServerSentBackGoLikeOtherAgentsAndAreNeverCountedLost) {
  // Map sharing may send an agent its own old keyframes (share_own_keyframes_after_s): the
  // ack tracker has long forgotten them, but the server has them, so trimming them is no loss.
  Chain chain;
  LocalMapBound bound(1, {4, 2});
  SetAck none;
  Map& map = chain.builder.map();
  std::vector<KeyframeId> returned;
  for (int i = 0; i < 3; ++i) {
    const KeyframeId id = chain.builder.AddKeyframe(100.0 + i);  // agent 1's, as the server sends them
    map.UpdateConnections(id);
    bound.OnKeyframeInserted(id, /*from_server=*/true);
    returned.push_back(id);
  }
  for (int i = 0; i < 5; ++i) bound.Trim(&map, chain.Add(&bound), none);
  // 8 keyframes over N + B = 6: the two oldest returned ones go first, as foreign ones would.
  EXPECT_EQ(map.num_keyframes(), 6u);
  EXPECT_EQ(bound.stats().removed_foreign, 2);
  EXPECT_EQ(bound.stats().removed_lost, 0);
  EXPECT_EQ(map.keyframe(returned[0]), nullptr);
  EXPECT_EQ(map.keyframe(returned[1]), nullptr);
  // Without the flag the same keyframes would have been unacknowledged own data, and lost.
  Chain plain;
  LocalMapBound plain_bound(1, {4, 2});
  for (int i = 0; i < 8; ++i) plain_bound.Trim(&plain.builder.map(), plain.Add(&plain_bound), none);
  EXPECT_EQ(plain_bound.stats().removed_lost, 2);
}

TEST(LocalMapBound, WithoutAcksKeepsAtMostNPlusBAndCountsLoss) {
  Chain chain;
  LocalMapBound bound(1, {10, 10});
  AckNone none;
  for (int i = 0; i < 100; ++i) {
    const KeyframeId kf = chain.Add(&bound);
    bound.Trim(&chain.builder.map(), kf, none);
    EXPECT_LE(chain.builder.map().num_keyframes(), 20u);
  }
  EXPECT_EQ(bound.stats().removed_lost, 80);
  EXPECT_EQ(bound.stats().removed_acked, 0);
  // The survivors are the 20 newest.
  EXPECT_NE(chain.builder.map().keyframe(chain.ids[80]), nullptr);
  EXPECT_EQ(chain.builder.map().keyframe(chain.ids[79]), nullptr);
}

TEST(LocalMapBound, AcknowledgedKeyframesLeaveBeyondN) {
  Chain chain;
  LocalMapBound bound(1, {10, 10});
  AckAll all;
  for (int i = 0; i < 50; ++i) bound.Trim(&chain.builder.map(), chain.Add(&bound), all);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 10u);
  EXPECT_EQ(bound.stats().removed_acked, 40);
  EXPECT_EQ(bound.stats().removed_lost, 0);
}

TEST(LocalMapBound, UnackedOnesWaitInTheBufferUntilAcked) {
  Chain chain;
  LocalMapBound bound(1, {5, 5});
  SetAck acks;
  for (int i = 0; i < 8; ++i) bound.Trim(&chain.builder.map(), chain.Add(&bound), acks);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 8u) << "within N+B nothing unacked is dropped";
  acks.acked.insert(chain.ids[0]);
  acks.acked.insert(chain.ids[1]);
  bound.Trim(&chain.builder.map(), chain.ids.back(), acks);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 6u);
  EXPECT_EQ(bound.stats().removed_acked, 2);
}

TEST(LocalMapBound, ReferenceKeyframeIsNeverRemoved) {
  Chain chain;
  LocalMapBound bound(1, {3, 0});
  AckAll all;
  for (int i = 0; i < 10; ++i) chain.Add(&bound);
  bound.Trim(&chain.builder.map(), chain.ids[0], all);  // the oldest is the reference
  EXPECT_NE(chain.builder.map().keyframe(chain.ids[0]), nullptr);
  EXPECT_EQ(chain.builder.map().num_keyframes(), 3u);
}

TEST(LocalMapBound, ForeignKeyframesGoFirstWhenOverBudget) {
  // Keyframes of agent 1 (own) plus keyframes received from agent 2 via the server.
  testing::MapBuilder b(200);
  LocalMapBound bound(1, {4, 2});
  AckNone none;
  std::vector<KeyframeId> own;
  Map& map = b.map();
  for (int i = 0; i < 6; ++i) {
    own.push_back(b.AddKeyframe(i));
    bound.OnKeyframeInserted(own.back());
  }
  // Two foreign keyframes, ids from agent 2, inserted after own ones.
  for (int i = 0; i < 2; ++i) {
    auto f = std::make_shared<FrameFeatures>(map.keyframe(own[0])->features());
    auto kf = std::make_shared<KeyFrame>(KeyframeId::Make(2, 100 + i), 0, map.keyframe(own[0])->camera_ptr(), f,
                                         std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2)), SE3());
    map.AddKeyframe(kf);
    bound.OnKeyframeInserted(kf->id());
  }
  own.push_back(b.AddKeyframe(7));
  bound.OnKeyframeInserted(own.back());
  // 9 keyframes, limit 6: both foreign ones go before any own keyframe is lost.
  bound.Trim(&map, own.back(), none);
  EXPECT_EQ(map.num_keyframes(), 6u);
  EXPECT_EQ(bound.stats().removed_foreign, 2);
  EXPECT_EQ(bound.stats().removed_lost, 1);
  EXPECT_EQ(map.keyframe(own[0]), nullptr) << "the oldest own keyframe is the one lost";
}

}  // namespace
}  // namespace ccm
