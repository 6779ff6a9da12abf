#include "slam_core/place_recognition/bow_vector.h"

#include <algorithm>
#include <cmath>

namespace ccm {

float BowVector::Weight(WordId word) const {
  auto it = std::lower_bound(entries.begin(), entries.end(), word,
                             [](const std::pair<WordId, float>& e, WordId w) { return e.first < w; });
  return (it != entries.end() && it->first == word) ? it->second : 0.f;
}

void BowVector::NormalizeL1() {
  double sum = 0.0;
  for (const auto& e : entries) sum += std::fabs(e.second);
  if (sum <= 0.0) return;
  const float inv = static_cast<float>(1.0 / sum);
  for (auto& e : entries) e.second *= inv;
}

double ScoreL1(const BowVector& a, const BowVector& b) {
  // For L1-normalized vectors |a-b|_1 = 2 - sum over common words of (|ai| + |bi| - |ai-bi|),
  // so only the common words need visiting (DBoW2's formulation).
  double acc = 0.0;
  auto ia = a.entries.begin(), ib = b.entries.begin();
  while (ia != a.entries.end() && ib != b.entries.end()) {
    if (ia->first < ib->first) {
      ++ia;
    } else if (ib->first < ia->first) {
      ++ib;
    } else {
      const double va = ia->second, vb = ib->second;
      acc += std::fabs(va) + std::fabs(vb) - std::fabs(va - vb);
      ++ia;
      ++ib;
    }
  }
  return std::clamp(0.5 * acc, 0.0, 1.0);
}

void CommonNodeGroups(const FeatureVector& a, const FeatureVector& b,
                      std::vector<std::vector<int>>* groups_a,
                      std::vector<std::vector<int>>* groups_b) {
  groups_a->clear();
  groups_b->clear();
  auto ia = a.nodes.begin(), ib = b.nodes.begin();
  while (ia != a.nodes.end() && ib != b.nodes.end()) {
    if (ia->first < ib->first) {
      ++ia;
    } else if (ib->first < ia->first) {
      ++ib;
    } else {
      groups_a->push_back(ia->second);
      groups_b->push_back(ib->second);
      ++ia;
      ++ib;
    }
  }
}

std::vector<NodeId> NodesOfFeatures(const FeatureVector& features, std::size_t num_features) {
  std::vector<NodeId> out(num_features, kNoNode);
  for (const auto& [node, indices] : features.nodes) {
    for (const int i : indices) {
      if (i >= 0 && static_cast<std::size_t>(i) < num_features) out[i] = node;
    }
  }
  return out;
}

FeatureVector FeatureVectorOf(const std::vector<NodeId>& node_per_feature) {
  std::vector<std::pair<NodeId, int>> pairs;
  pairs.reserve(node_per_feature.size());
  for (std::size_t i = 0; i < node_per_feature.size(); ++i) {
    if (node_per_feature[i] != kNoNode) pairs.emplace_back(node_per_feature[i], static_cast<int>(i));
  }
  std::sort(pairs.begin(), pairs.end());
  FeatureVector out;
  for (const auto& [node, i] : pairs) {
    if (out.nodes.empty() || out.nodes.back().first != node) out.nodes.emplace_back(node, std::vector<int>{});
    out.nodes.back().second.push_back(i);
  }
  return out;
}

}  // namespace ccm
