// Keyframe database: an inverted file (word -> keyframes containing it, with the word's
// weight) over the bags of words of all keyframes of all maps on the server. Queries score
// only keyframes sharing words with the query and can be restricted to some maps/agents (loop
// detection: the query's own map; merging: every other map). DetectCandidates adds ORB-SLAM's
// covisibility-consistency grouping. Thread-safe: Add/Erase/ReassignMap take a unique lock,
// queries a shared lock. The database never calls out while it holds its lock (the
// covisibility callback runs unlocked), so callers may hold map locks while calling it and the
// callback may lock maps: no lock-order constraint.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <shared_mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/place_recognition/bow_vector.h"

namespace ccm {

/// Which keyframes a query may return. Empty lists mean "no restriction".
struct QueryFilter {
  std::vector<MapId> only_maps;        ///< if non-empty: only keyframes of these maps
  std::vector<MapId> exclude_maps;     ///< never keyframes of these maps
  std::vector<AgentId> only_agents;    ///< if non-empty: only keyframes of these agents
  std::vector<KeyframeId> exclude_keyframes;  ///< e.g. the query's covisible keyframes
};

/// One scored database keyframe.
struct QueryResult {
  KeyframeId keyframe;
  MapId map;
  AgentId agent = 0;
  double score = 0.0;      ///< L1 score against the query, [0, 1]
  int common_words = 0;    ///< words shared with the query
};

/// A place candidate after covisibility grouping: the best keyframe of a consistent group.
struct PlaceCandidate {
  QueryResult best;            ///< highest-scoring keyframe of the group
  double group_score = 0.0;    ///< accumulated score of the candidate and its covisible neighbours
};

struct CandidateOptions {
  double min_score = 0.0;              ///< candidates must score >= this (loops: min over covisible)
  double min_common_ratio = 0.8;       ///< keep keyframes sharing >= ratio * max shared words
  double group_ratio = 0.75;           ///< keep groups scoring >= ratio * best group
  int covisible_neighbours = 10;       ///< neighbours asked from the callback per candidate
  int max_results = 0;                 ///< 0 = all groups that pass
  std::string Validate() const;
};

/// Best covisible keyframes of a keyframe (most shared map points first), at most n.
using CovisibilityFn = std::function<std::vector<KeyframeId>(KeyframeId keyframe, int n)>;

class KeyframeDatabase {
 public:
  /// `num_words` = Vocabulary::num_words() of the vocabulary producing the bags of words.
  explicit KeyframeDatabase(std::size_t num_words);

  /// Inserts (or replaces) a keyframe. The agent is keyframe.agent().
  void Add(KeyframeId keyframe, MapId map, const BowVector& bow);
  /// Removes a keyframe; false if unknown.
  bool Erase(KeyframeId keyframe);
  /// Moves every keyframe of map `from` to map `to` (after a map merge). Returns how many.
  std::size_t ReassignMap(MapId from, MapId to);
  void Clear();

  std::size_t size() const;
  bool Contains(KeyframeId keyframe) const;
  /// Stored bag of words of a keyframe.
  std::optional<BowVector> GetBow(KeyframeId keyframe) const;

  /// All keyframes passing `filter` that share at least one word with `query`, sorted by
  /// score (then id), at most max_results (0 = all).
  std::vector<QueryResult> Query(const BowVector& query, const QueryFilter& filter,
                                 std::size_t max_results = 0) const;

  /// ORB-SLAM candidate selection: keyframes sharing >= min_common_ratio * max words and
  /// scoring >= min_score; each is grouped with its covisible neighbours among those, groups
  /// accumulate their scores and those >= group_ratio * best survive, represented by their
  /// best keyframe. Sorted by group score. Without `covisibility` each keyframe is its own group.
  std::vector<PlaceCandidate> DetectCandidates(const BowVector& query, const QueryFilter& filter,
                                               const CandidateOptions& options,
                                               const CovisibilityFn& covisibility = {}) const;

  /// Lowest score between `query` and the stored keyframes `neighbours` (unknown ones are
  /// skipped); 1 if none is known. ORB-SLAM's minimum score for loop candidates.
  double MinScore(const BowVector& query, const std::vector<KeyframeId>& neighbours) const;

 private:
  struct Posting {
    std::uint32_t slot;
    float weight;
  };
  struct Slot {
    KeyframeId keyframe;
    MapId map;
    AgentId agent = 0;
    bool alive = false;
    BowVector bow;
  };
  void EraseLocked(KeyframeId keyframe);

  mutable std::shared_mutex mutex_;
  std::vector<std::vector<Posting>> inverted_;  // word -> postings
  std::vector<Slot> slots_;
  std::vector<std::uint32_t> free_slots_;
  std::unordered_map<KeyframeId, std::uint32_t> slot_of_;
};

}  // namespace ccm
