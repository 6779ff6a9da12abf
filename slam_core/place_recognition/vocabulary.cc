#include "slam_core/place_recognition/vocabulary.h"

#include <algorithm>

namespace ccm {

std::string VocabularyOptions::Validate() const {
  if (branching < 2 || branching > 64) return "branching must be in [2, 64]";
  if (levels < 1 || levels > 10) return "levels must be in [1, 10]";
  if (max_iterations < 1) return "max_iterations must be >= 1";
  if (threads < 1 || threads > 256) return "threads must be in [1, 256]";
  double leaves = 1.0;
  for (int l = 0; l < levels; ++l) leaves *= branching;
  if (leaves > 2e8) return "branching^levels must be <= 2e8 words";
  return {};
}

std::string Vocabulary::Assign(int branching, int levels, std::vector<Node> nodes) {
  branching_ = 0;
  levels_ = 0;
  nodes_.clear();
  words_.clear();
  if (branching < 2 || branching > 64) return "branching must be in [2, 64]";
  if (levels < 1 || levels > 10) return "levels must be in [1, 10]";
  if (nodes.empty()) return "vocabulary has no nodes";
  // Re-derive children ranges, depths and word ids from the parent links: children must
  // follow their parent and be contiguous (the layout Train produces).
  nodes[0].parent = 0;
  nodes[0].depth = 0;
  for (auto& n : nodes) {
    n.num_children = 0;
    n.first_child = 0;
  }
  std::vector<NodeId> words;
  for (std::size_t i = 1; i < nodes.size(); ++i) {
    const NodeId p = nodes[i].parent;
    if (p >= i) return "node " + std::to_string(i) + " has parent " + std::to_string(p) + " after it";
    Node& parent = nodes[p];
    if (parent.num_children == 0) {
      parent.first_child = static_cast<NodeId>(i);
    } else if (parent.first_child + parent.num_children != i) {
      return "children of node " + std::to_string(p) + " are not contiguous";
    }
    if (++parent.num_children > static_cast<std::uint32_t>(branching)) {
      return "node " + std::to_string(p) + " has more than " + std::to_string(branching) + " children";
    }
    nodes[i].depth = parent.depth + 1;
    if (nodes[i].depth > static_cast<std::uint32_t>(levels)) return "tree deeper than its levels";
  }
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].num_children == 0 && i != 0) {
      nodes[i].word = static_cast<WordId>(words.size());
      words.push_back(static_cast<NodeId>(i));
    } else {
      nodes[i].word = kNoWord;
    }
  }
  if (words.empty()) return "vocabulary has no words";
  branching_ = branching;
  levels_ = levels;
  nodes_ = std::move(nodes);
  words_ = std::move(words);
  return {};
}

WordId Vocabulary::Transform(const OrbDescriptor& descriptor, NodeId* node_at_level,
                             int level) const {
  NodeId id = 0;
  if (node_at_level) *node_at_level = 0;
  while (nodes_[id].num_children > 0) {
    const Node& n = nodes_[id];
    NodeId best = n.first_child;
    int best_d = 257;
    for (NodeId c = n.first_child; c < n.first_child + n.num_children; ++c) {
      const int d = HammingDistance(descriptor, nodes_[c].descriptor);
      if (d < best_d) {
        best_d = d;
        best = c;
      }
    }
    id = best;
    if (node_at_level && static_cast<int>(nodes_[id].depth) <= level) *node_at_level = id;
  }
  return nodes_[id].word;
}

void Vocabulary::Transform(const std::vector<OrbDescriptor>& descriptors, BowVector* bow,
                           FeatureVector* features, int levels_up) const {
  bow->entries.clear();
  if (features) features->nodes.clear();
  if (empty()) return;
  const int level = std::max(1, levels_ - levels_up);
  std::vector<std::pair<WordId, float>> words;
  std::vector<NodeId> node_of_feature;
  words.reserve(descriptors.size());
  if (features) node_of_feature.assign(descriptors.size(), kNoNode);
  for (std::size_t i = 0; i < descriptors.size(); ++i) {
    const WordId w = Transform(descriptors[i], features ? &node_of_feature[i] : nullptr, level);
    words.emplace_back(w, WordWeight(w));
  }
  // TF-IDF: each occurrence adds the word's IDF; the L1 normalization divides by the count.
  std::sort(words.begin(), words.end());
  for (const auto& w : words) {
    if (!bow->entries.empty() && bow->entries.back().first == w.first) {
      bow->entries.back().second += w.second;
    } else {
      bow->entries.push_back(w);
    }
  }
  bow->entries.erase(std::remove_if(bow->entries.begin(), bow->entries.end(),
                                    [](const std::pair<WordId, float>& e) { return e.second <= 0.f; }),
                     bow->entries.end());
  bow->NormalizeL1();
  if (features) *features = FeatureVectorOf(node_of_feature);
}

}  // namespace ccm
