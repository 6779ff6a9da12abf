// KeyframeDatabase: insert/erase/query with map/agent/keyframe filters, covisibility grouping,
// concurrent inserts and queries.
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <random>
#include <thread>

#include "slam_core/place_recognition/keyframe_database.h"

namespace ccm {
namespace {

constexpr size_t kWords = 1000;

// A random bag of 50 words; "place" p uses words [p*40, p*40 + 60) so neighbouring places
// share some words and distant ones none.
BowVector PlaceBow(int place, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::map<WordId, float> words;
  for (int i = 0; i < 50; ++i) words[static_cast<WordId>((place * 40 + rng() % 60) % kWords)] += 1.f;
  BowVector bow;
  bow.entries.assign(words.begin(), words.end());
  bow.NormalizeL1();
  return bow;
}

KeyframeId Kf(AgentId agent, uint64_t n) { return KeyframeId::Make(agent, n); }
MapId MapOf(AgentId agent) { return MapId::Make(agent, 1); }

TEST(KeyframeDatabaseTest, InsertQueryErase) {
  KeyframeDatabase db(kWords);
  for (int p = 0; p < 20; ++p) db.Add(Kf(1, p + 1), MapOf(1), PlaceBow(p, p));
  EXPECT_EQ(db.size(), 20u);
  const BowVector q = PlaceBow(7, 1234);
  auto results = db.Query(q, {});
  ASSERT_FALSE(results.empty());
  EXPECT_EQ(results[0].keyframe, Kf(1, 8));
  EXPECT_EQ(results[0].map, MapOf(1));
  EXPECT_EQ(results[0].agent, 1);
  EXPECT_NEAR(results[0].score, ScoreL1(q, PlaceBow(7, 7)), 1e-5);
  for (size_t i = 1; i < results.size(); ++i) EXPECT_GE(results[i - 1].score, results[i].score);
  // Only places sharing words are returned (6, 7, 8 share, 5 and 9 barely or not).
  for (const auto& r : results) EXPECT_LE(std::abs(static_cast<int>(r.keyframe.counter()) - 8), 2);

  EXPECT_EQ(db.Query(q, {}, 1).size(), 1u);
  // Identical bag of words scores 1.
  EXPECT_NEAR(db.Query(PlaceBow(3, 3), {}, 1)[0].score, 1.0, 1e-5);

  EXPECT_TRUE(db.Erase(Kf(1, 8)));
  EXPECT_FALSE(db.Erase(Kf(1, 8)));
  EXPECT_FALSE(db.Contains(Kf(1, 8)));
  results = db.Query(q, {});
  for (const auto& r : results) EXPECT_NE(r.keyframe, Kf(1, 8));
  // Re-adding reuses the freed slot and is found again.
  db.Add(Kf(1, 8), MapOf(1), PlaceBow(7, 7));
  EXPECT_EQ(db.Query(q, {}, 1)[0].keyframe, Kf(1, 8));
  // Replacing a keyframe's bag of words does not duplicate it.
  db.Add(Kf(1, 8), MapOf(1), PlaceBow(7, 7));
  EXPECT_EQ(db.size(), 20u);
  EXPECT_EQ(db.Query(PlaceBow(7, 7), {}).size(), db.Query(PlaceBow(7, 7), {}).size());
}

TEST(KeyframeDatabaseTest, MapAgentAndKeyframeFilters) {
  KeyframeDatabase db(kWords);
  // Agents 1 and 2 both visit places 0..9 (maps 1 and 2); agent 3 visits 5..9 in map 3.
  for (int p = 0; p < 10; ++p) {
    db.Add(Kf(1, p + 1), MapOf(1), PlaceBow(p, 100 + p));
    db.Add(Kf(2, p + 1), MapOf(2), PlaceBow(p, 200 + p));
    if (p >= 5) db.Add(Kf(3, p + 1), MapOf(3), PlaceBow(p, 300 + p));
  }
  const BowVector q = PlaceBow(6, 999);
  QueryFilter only1;
  only1.only_maps = {MapOf(1)};
  for (const auto& r : db.Query(q, only1)) EXPECT_EQ(r.map, MapOf(1));
  QueryFilter not1;
  not1.exclude_maps = {MapOf(1)};
  auto r = db.Query(q, not1);
  ASSERT_FALSE(r.empty());
  for (const auto& x : r) EXPECT_NE(x.map, MapOf(1));
  QueryFilter agent3;
  agent3.only_agents = {3};
  r = db.Query(q, agent3);
  ASSERT_FALSE(r.empty());
  for (const auto& x : r) EXPECT_EQ(x.agent, 3);
  QueryFilter no_kf;
  no_kf.exclude_keyframes = {Kf(1, 7), Kf(2, 7), Kf(3, 7)};
  for (const auto& x : db.Query(q, no_kf)) EXPECT_NE(x.keyframe.counter(), 7u);
  // After merging map 3 into map 2, map-2 queries see agent 3's keyframes.
  EXPECT_EQ(db.ReassignMap(MapOf(3), MapOf(2)), 5u);
  QueryFilter only2;
  only2.only_maps = {MapOf(2)};
  bool saw_agent3 = false;
  for (const auto& x : db.Query(q, only2)) saw_agent3 |= x.agent == 3;
  EXPECT_TRUE(saw_agent3);
}

TEST(KeyframeDatabaseTest, CovisibilityGroupingPrefersConsistentPlaces) {
  KeyframeDatabase db(kWords);
  // Place 10 is seen by three covisible keyframes (1..3); place 30 by one isolated keyframe
  // (4) whose single score is slightly higher than each of the group's.
  db.Add(Kf(1, 1), MapOf(1), PlaceBow(10, 1));
  db.Add(Kf(1, 2), MapOf(1), PlaceBow(10, 2));
  db.Add(Kf(1, 3), MapOf(1), PlaceBow(10, 3));
  BowVector mixed = PlaceBow(10, 50);
  const BowVector other = PlaceBow(30, 51);
  BowVector query;
  for (const auto& e : mixed.entries) query.entries.emplace_back(e.first, e.second * 0.5f);
  for (const auto& e : other.entries) query.entries.emplace_back(e.first, e.second * 0.5f);
  std::sort(query.entries.begin(), query.entries.end());
  db.Add(Kf(1, 4), MapOf(1), other);
  auto covis = [](KeyframeId kf, int) -> std::vector<KeyframeId> {
    if (kf.counter() >= 1 && kf.counter() <= 3) {
      std::vector<KeyframeId> n;
      for (uint64_t i = 1; i <= 3; ++i) if (i != kf.counter()) n.push_back(Kf(1, i));
      return n;
    }
    return {};
  };
  CandidateOptions options;
  options.min_common_ratio = 0.0;
  auto with = db.DetectCandidates(query, {}, options, covis);
  ASSERT_FALSE(with.empty());
  EXPECT_LE(with[0].best.keyframe.counter(), 3u);
  EXPECT_GT(with[0].group_score, with[0].best.score * 2);
  // A high minimum score removes everything.
  options.min_score = 0.99;
  EXPECT_TRUE(db.DetectCandidates(query, {}, options, covis).empty());
  EXPECT_LE(db.MinScore(PlaceBow(10, 1), {Kf(1, 1), Kf(1, 2)}), 1.0);
  EXPECT_NEAR(db.MinScore(PlaceBow(10, 1), {Kf(1, 1)}), 1.0, 1e-6);
  EXPECT_DOUBLE_EQ(db.MinScore(PlaceBow(10, 1), {Kf(9, 9)}), 1.0);
}

TEST(KeyframeDatabaseTest, ConcurrentInsertEraseAndQuery) {
  KeyframeDatabase db(kWords);
  std::atomic<bool> stop{false};
  std::atomic<int> queries{0};
  std::atomic<bool> bad{false};
  std::vector<std::thread> readers;
  for (int t = 0; t < 2; ++t) {
    readers.emplace_back([&, t] {
      int i = 0;
      while (!stop.load()) {
        auto r = db.Query(PlaceBow((i++ * 7 + t) % 25, 77), {}, 5);
        for (size_t k = 1; k < r.size(); ++k) bad = bad || r[k - 1].score < r[k].score;
        for (const auto& x : r) bad = bad || x.score < 0 || x.score > 1;
        ++queries;
      }
    });
  }
  std::vector<std::thread> writers;
  for (int a = 1; a <= 2; ++a) {
    writers.emplace_back([&db, a] {
      for (int p = 0; p < 400; ++p) {
        db.Add(Kf(a, p + 1), MapOf(a), PlaceBow(p % 25, p));
        if (p % 3 == 0) db.Erase(Kf(a, p / 2 + 1));
      }
    });
  }
  for (auto& w : writers) w.join();
  stop = true;
  for (auto& r : readers) r.join();
  EXPECT_FALSE(bad.load());
  EXPECT_GT(queries.load(), 0);
  // Each writer erased keyframes 1, 2, 4, 5, 7, ... (p/2+1 for p = 0, 3, 6, ...): 134 each.
  EXPECT_EQ(db.size(), 2u * (400 - 134));
  // Every remaining keyframe is still found by its own bag of words.
  for (int p = 0; p < 400; p += 37) {
    if (!db.Contains(Kf(1, p + 1))) continue;
    auto r = db.Query(PlaceBow(p % 25, p), {}, 1);
    ASSERT_FALSE(r.empty());
    EXPECT_NEAR(r[0].score, 1.0, 1e-5);
  }
}

}  // namespace
}  // namespace ccm
