// Internal helpers of the matchers (not part of the API): best/second-best tracking, the
// candidate pair enumeration and the one-to-one resolution shared by all matchers.
#pragma once

#include <algorithm>
#include <limits>
#include <vector>

#include "slam_core/matching/match_types.h"

namespace ccm::internal {

struct BestTwo {
  int index = -1;
  int best = std::numeric_limits<int>::max();
  int second = std::numeric_limits<int>::max();
  int best_level = -1;  ///< pyramid level of the best candidate (for same-level ratio tests)
  int second_level = -1;

  void Add(int candidate, int distance, int level = 0) {
    if (candidate == index) return;  // the same candidate seen twice is no competitor
    if (distance < best) {
      second = best;
      second_level = best_level;
      best = distance;
      best_level = level;
      index = candidate;
    } else if (distance < second) {
      second = distance;
      second_level = level;
    }
  }
  /// Ratio test best < ratio * second; ratio >= 1 or no second candidate passes.
  bool PassesRatio(double ratio) const {
    if (ratio >= 1.0 || second == std::numeric_limits<int>::max()) return true;
    return best < ratio * second;
  }
};

/// Calls visit(i, j) for every candidate pair: all pairs, or the pairs inside each group.
template <typename Visit>
void ForEachPair(size_t n1, size_t n2, const MatchGroups* groups, Visit&& visit) {
  if (groups == nullptr) {
    for (size_t i = 0; i < n1; ++i) {
      for (size_t j = 0; j < n2; ++j) visit(static_cast<int>(i), static_cast<int>(j));
    }
    return;
  }
  const size_t g_count = std::min(groups->groups1.size(), groups->groups2.size());
  for (size_t g = 0; g < g_count; ++g) {
    for (int i : groups->groups1[g]) {
      if (i < 0 || static_cast<size_t>(i) >= n1) continue;
      for (int j : groups->groups2[g]) {
        if (j >= 0 && static_cast<size_t>(j) < n2) visit(i, j);
      }
    }
  }
}

/// Turns per-query bests into one-to-one matches: queries passing `accept` claim their best
/// candidate and the smallest distance keeps it (ties: lower query index). Sorted by index1.
template <typename Accept>
std::vector<FeatureMatch> ResolveOneToOne(const std::vector<BestTwo>& best, size_t num_candidates,
                                          Accept&& accept) {
  std::vector<int> owner(num_candidates, -1);
  for (size_t i = 0; i < best.size(); ++i) {
    const BestTwo& b = best[i];
    if (b.index < 0 || !accept(static_cast<int>(i), b)) continue;
    int& o = owner[b.index];
    if (o < 0 || b.best < best[o].best) o = static_cast<int>(i);
  }
  std::vector<FeatureMatch> matches;
  for (size_t i = 0; i < best.size(); ++i) {
    const BestTwo& b = best[i];
    if (b.index >= 0 && owner[b.index] == static_cast<int>(i)) {
      matches.push_back({static_cast<int>(i), b.index, b.best});
    }
  }
  return matches;
}

}  // namespace ccm::internal
