// Binary bag-of-words vocabulary for 256-bit ORB descriptors: a tree of k-majority cluster
// centres (k children per node, up to L levels) whose leaves are the words, with TF-IDF word
// weights and L1 scoring (the DBoW2 scheme used by ORB-SLAM and CCM-SLAM).
// Build it with Vocabulary::Train (deterministic for a seed) or load it with
// LoadVocabularyFile (vocabulary_io.h). Immutable after construction: const methods are safe
// from any number of threads at once.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "slam_core/feature/orb_types.h"
#include "slam_core/place_recognition/bow_vector.h"

namespace ccm {

struct VocabularyOptions {
  int branching = 10;          ///< k: children per node, >= 2
  int levels = 6;              ///< L: depth of the tree (leaves at most L below the root), >= 1
  int max_iterations = 10;     ///< k-majority iterations per node (stops earlier on convergence)
  /// Descriptors used for clustering; larger inputs are subsampled uniformly (all descriptors
  /// still count for the IDF weights). 0 = use all.
  std::size_t max_descriptors = 1'000'000;
  std::uint64_t seed = 1;      ///< seeds k-means++ and subsampling: same input + seed = same tree
  /// Threads for the distance and majority passes over big nodes (>= 1). The tree is the
  /// same for any count: each pass splits its descriptors into fixed ranges whose results
  /// are exact integers merged in order.
  int threads = 1;

  /// Empty if usable, else what is wrong ("branching must be in [2, 64]").
  std::string Validate() const;
};

/// Training progress: stage name and completed fraction in [0, 1].
struct TrainingProgress {
  std::string stage;  ///< "clustering" or "weighting"
  double fraction = 0.0;
};
using TrainingProgressCallback = std::function<void(const TrainingProgress&)>;

class Vocabulary {
 public:
  /// One tree node. Node 0 is the root (no descriptor); the children of a node are stored
  /// contiguously at [first_child, first_child + num_children).
  struct Node {
    OrbDescriptor descriptor{};
    NodeId parent = 0;
    NodeId first_child = 0;
    std::uint32_t num_children = 0;
    std::uint32_t depth = 0;        ///< root 0, its children 1, ...
    WordId word = kNoWord;          ///< word id if this is a leaf
    float weight = 0.f;             ///< IDF weight (leaves)
  };
  static constexpr WordId kNoWord = 0xffffffffu;

  Vocabulary() = default;

  /// Trains on the descriptors of a set of images (one vector per image; the image grouping
  /// gives the IDF weights). Options must be valid. `progress` is called from this thread.
  static Vocabulary Train(const std::vector<std::vector<OrbDescriptor>>& images,
                          const VocabularyOptions& options,
                          const TrainingProgressCallback& progress = {});

  /// Builds a vocabulary from nodes (loading code). Empty string if the tree is valid,
  /// else the problem; on error *this is left empty.
  std::string Assign(int branching, int levels, std::vector<Node> nodes);

  bool empty() const { return words_.empty(); }
  int branching() const { return branching_; }
  int levels() const { return levels_; }
  std::size_t num_words() const { return words_.size(); }
  std::size_t num_nodes() const { return nodes_.size(); }
  const std::vector<Node>& nodes() const { return nodes_; }
  float WordWeight(WordId word) const { return nodes_[words_[word]].weight; }
  NodeId WordNode(WordId word) const { return words_[word]; }

  /// Word of one descriptor (greedy descent, nearest child by Hamming distance at each level).
  /// `node_at_level` (optional) receives the ancestor at depth `level` (or the leaf if shallower).
  WordId Transform(const OrbDescriptor& descriptor, NodeId* node_at_level = nullptr,
                   int level = 0) const;

  /// TF-IDF bag of words of an image (L1-normalized, zero-weight words dropped) and, if
  /// `features` is given, the direct index at depth levels() - levels_up (at least 1):
  /// node -> indices into `descriptors`.
  void Transform(const std::vector<OrbDescriptor>& descriptors, BowVector* bow,
                 FeatureVector* features = nullptr, int levels_up = 4) const;

  /// L1 score (see ScoreL1).
  double Score(const BowVector& a, const BowVector& b) const { return ScoreL1(a, b); }

 private:
  friend class VocabularyTrainer;
  int branching_ = 0;
  int levels_ = 0;
  std::vector<Node> nodes_;
  std::vector<NodeId> words_;  // word id -> node
};

}  // namespace ccm
