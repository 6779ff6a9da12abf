// Bag-of-words value types: a sparse, L1-normalized word histogram (BowVector) and the direct
// index (FeatureVector: vocabulary node -> indices of the features under it). Both are plain
// sorted vectors so they are cheap to copy into messages and to merge-scan when scoring.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace ccm {

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

/// Sparse word -> weight histogram, entries sorted by word id with unique words.
/// After Vocabulary::Transform the weights are TF-IDF and sum to 1 (L1 norm).
struct BowVector {
  std::vector<std::pair<WordId, float>> entries;

  bool empty() const { return entries.empty(); }
  std::size_t size() const { return entries.size(); }
  /// Weight of `word` (0 if absent); binary search.
  float Weight(WordId word) const;
  /// Scales the weights so their absolute values sum to 1 (no-op for an empty vector).
  void NormalizeL1();
};

/// L1 similarity of two L1-normalized vectors: 1 - 0.5 * |a - b|_1, in [0, 1];
/// identical vectors score 1, vectors without a common word score 0.
double ScoreL1(const BowVector& a, const BowVector& b);

/// Direct index: for each vocabulary node at a chosen level, the indices of the features of
/// one image that fall under it. Sorted by node id. Features under the same node are the only
/// match candidates for each other in BoW-guided matching.
struct FeatureVector {
  std::vector<std::pair<NodeId, std::vector<int>>> nodes;

  bool empty() const { return nodes.empty(); }
  std::size_t size() const { return nodes.size(); }
};

/// The direct index as one node per feature (index = feature), the compact form to keep per
/// keyframe; kNoNode for features the index does not hold.
constexpr NodeId kNoNode = ~NodeId{0};
std::vector<NodeId> NodesOfFeatures(const FeatureVector& features, std::size_t num_features);
/// Back from one node per feature to the direct index (kNoNode entries left out).
FeatureVector FeatureVectorOf(const std::vector<NodeId>& node_per_feature);

/// Features of `a` and `b` that share a node: groups1[g] of a may match groups2[g] of b.
/// Merge-scan over both sorted lists (the layout of ccm::MatchGroups).
void CommonNodeGroups(const FeatureVector& a, const FeatureVector& b,
                      std::vector<std::vector<int>>* groups_a,
                      std::vector<std::vector<int>>* groups_b);

}  // namespace ccm
