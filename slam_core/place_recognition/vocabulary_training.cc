// Hierarchical k-majority clustering (k-medians in Hamming space) with k-means++ seeding.
// Each node's random stream is seeded from (seed, node id), so the tree only depends on the
// input and the seed. Clustering works in place on one index array partitioned per child.
// Big nodes split their distance and majority passes over options.threads threads; what the
// parts return are exact integers (squared Hamming distances in doubles stay below 2^53),
// merged in part order, so the tree does not depend on the thread count.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "slam_core/place_recognition/vocabulary.h"

namespace ccm {

namespace {

// splitmix64: small, portable, deterministic on every platform (unlike std distributions).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  std::size_t Uniform(std::size_t n) { return static_cast<std::size_t>(Next() % n); }
  double Unit() { return static_cast<double>(Next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  std::uint64_t state_;
};

// Nodes with fewer descriptors than this run on the calling thread: starting a thread costs
// more than their pass.
constexpr std::size_t kMinParallelDescriptors = 4096;

// Runs fn(part, begin, end) over [0, n) cut into `parts` contiguous ranges, part 0 on the
// calling thread; returns when all have finished.
template <typename Fn>
void ForParts(std::size_t parts, std::size_t n, Fn&& fn) {
  std::vector<std::thread> workers;
  for (std::size_t p = 1; p < parts; ++p) {
    workers.emplace_back([&fn, p, parts, n] { fn(p, n * p / parts, n * (p + 1) / parts); });
  }
  fn(0, 0, n / parts);
  for (auto& w : workers) w.join();
}

using BitCounts = std::array<std::uint32_t, 256>;

// Adds how often each of the 256 bits is set in data[begin..end). Bigger sets count byte
// values first (32 increments per descriptor instead of 256 bit tests) and expand the 32
// byte histograms once at the end.
void AddBitCounts(const std::vector<const OrbDescriptor*>& data, const std::uint32_t* begin,
                  const std::uint32_t* end, BitCounts* counts) {
  if (end - begin < 512) {
    for (const std::uint32_t* it = begin; it != end; ++it) {
      const OrbDescriptor& d = *data[*it];
      for (int byte = 0; byte < 32; ++byte) {
        const std::uint8_t b = d[byte];
        for (int bit = 0; bit < 8; ++bit) (*counts)[byte * 8 + bit] += (b >> (7 - bit)) & 1u;
      }
    }
    return;
  }
  std::vector<std::uint32_t> histogram(32 * 256, 0);
  for (const std::uint32_t* it = begin; it != end; ++it) {
    const OrbDescriptor& d = *data[*it];
    for (int byte = 0; byte < 32; ++byte) ++histogram[byte * 256 + d[byte]];
  }
  for (int byte = 0; byte < 32; ++byte) {
    for (int value = 0; value < 256; ++value) {
      const std::uint32_t c = histogram[byte * 256 + value];
      if (c == 0) continue;
      for (int bit = 0; bit < 8; ++bit) {
        if ((value >> (7 - bit)) & 1) (*counts)[byte * 8 + bit] += c;
      }
    }
  }
}

// Bitwise majority of data[begin..end) (ties give 0). Counts are integers, so splitting the
// range over threads gives the same centre.
OrbDescriptor Majority(const std::vector<const OrbDescriptor*>& data, const std::uint32_t* begin,
                       const std::uint32_t* end, std::size_t parts) {
  std::vector<BitCounts> counts(parts, BitCounts{});
  ForParts(parts, static_cast<std::size_t>(end - begin), [&](std::size_t p, std::size_t b, std::size_t e) {
    AddBitCounts(data, begin + b, begin + e, &counts[p]);
  });
  for (std::size_t p = 1; p < parts; ++p) {
    for (int i = 0; i < 256; ++i) counts[0][i] += counts[p][i];
  }
  const std::size_t n = static_cast<std::size_t>(end - begin);
  OrbDescriptor out{};
  for (int i = 0; i < 256; ++i) {
    if (2 * counts[0][i] > n) out[i / 8] |= static_cast<std::uint8_t>(1u << (7 - i % 8));
  }
  return out;
}

}  // namespace

// Builds the tree; a friend of Vocabulary so it can fill the node array directly.
class VocabularyTrainer {
 public:
  VocabularyTrainer(const VocabularyOptions& options, const TrainingProgressCallback& progress)
      : options_(options), progress_(progress) {}

  Vocabulary Run(const std::vector<std::vector<OrbDescriptor>>& images) {
    for (const auto& image : images) {
      for (const auto& d : image) data_.push_back(&d);
    }
    Subsample();
    nodes_.assign(1, Vocabulary::Node{});
    std::vector<std::uint32_t> index(data_.size());
    for (std::size_t i = 0; i < index.size(); ++i) index[i] = static_cast<std::uint32_t>(i);
    if (!index.empty()) Cluster(0, index.data(), index.data() + index.size());
    Vocabulary vocab;
    vocab.Assign(options_.branching, options_.levels, std::move(nodes_));
    ComputeIdf(images, &vocab);
    return vocab;
  }

 private:
  void Subsample() {
    if (options_.max_descriptors == 0 || data_.size() <= options_.max_descriptors) return;
    Rng rng(options_.seed ^ 0x5b5a3c1d2e4f6071ull);
    // Partial Fisher-Yates: the first max_descriptors entries are a uniform sample.
    for (std::size_t i = 0; i < options_.max_descriptors; ++i) {
      std::swap(data_[i], data_[i + rng.Uniform(data_.size() - i)]);
    }
    data_.resize(options_.max_descriptors);
  }

  void Report(const char* stage, double fraction) {
    if (!progress_) return;
    if (stage != last_stage_) {
      last_stage_ = stage;
      last_reported_ = -1.0;
    }
    if (fraction < 1.0 && fraction - last_reported_ < 0.01) return;
    last_reported_ = fraction;
    progress_(TrainingProgress{stage, fraction});
  }

  // Clusters data_[index[begin..end)] under node `parent`, then recurses into each child.
  void Cluster(NodeId parent, std::uint32_t* begin, std::uint32_t* end) {
    const std::size_t n = static_cast<std::size_t>(end - begin);
    const std::uint32_t depth = nodes_[parent].depth;
    const std::size_t k = static_cast<std::size_t>(options_.branching);
    std::vector<OrbDescriptor> centres;
    std::vector<std::uint32_t*> bounds;  // child c owns [bounds[c], bounds[c+1])
    if (n <= k) {
      // Few descriptors: each distinct one becomes a leaf.
      std::sort(begin, end, [&](std::uint32_t a, std::uint32_t b) { return *data_[a] < *data_[b]; });
      for (std::uint32_t* it = begin; it != end; ++it) {
        if (centres.empty() || centres.back() != *data_[*it]) {
          centres.push_back(*data_[*it]);
          bounds.push_back(it);
        }
      }
      bounds.push_back(end);
    } else {
      KMajority(parent, begin, end, &centres, &bounds);
    }
    const NodeId first = static_cast<NodeId>(nodes_.size());
    for (const auto& c : centres) {
      Vocabulary::Node node;
      node.descriptor = c;
      node.parent = parent;
      node.depth = depth + 1;
      nodes_.push_back(node);
    }
    const bool leaves = n <= k || depth + 1 >= static_cast<std::uint32_t>(options_.levels);
    for (std::size_t c = 0; c < centres.size(); ++c) {
      const std::size_t size = static_cast<std::size_t>(bounds[c + 1] - bounds[c]);
      if (leaves || size <= 1) {
        done_ += size;
        Report("clustering", static_cast<double>(done_) / data_.size());
      } else {
        Cluster(first + static_cast<NodeId>(c), bounds[c], bounds[c + 1]);
      }
    }
  }

  // k-means++ seeding then Lloyd iterations with bitwise-majority centres. Empty clusters are
  // dropped. On return the index range is partitioned by cluster.
  void KMajority(NodeId parent, std::uint32_t* begin, std::uint32_t* end,
                 std::vector<OrbDescriptor>* centres, std::vector<std::uint32_t*>* bounds) {
    const std::size_t n = static_cast<std::size_t>(end - begin);
    const std::size_t k = static_cast<std::size_t>(options_.branching);
    Rng rng(options_.seed * 0x100000001b3ull + parent * 0x9e3779b97f4a7c15ull + 1);
    SeedPlusPlus(begin, n, k, &rng, centres);
    const std::size_t parts = PartsFor(n);
    std::vector<std::uint16_t> assign(n, 0xffff);
    for (int iter = 0; iter < options_.max_iterations; ++iter) {
      std::vector<char> changed(parts, 0);
      ForParts(parts, n, [&](std::size_t p, std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          const OrbDescriptor& d = *data_[begin[i]];
          int best_d = 257;
          std::uint16_t best = 0;
          for (std::size_t c = 0; c < centres->size(); ++c) {
            const int dist = HammingDistance(d, (*centres)[c]);
            if (dist < best_d) {
              best_d = dist;
              best = static_cast<std::uint16_t>(c);
            }
          }
          if (assign[i] != best) changed[p] = 1;
          assign[i] = best;
        }
      });
      PartitionByCluster(begin, &assign, centres->size(), bounds);
      const bool any_changed = std::find(changed.begin(), changed.end(), 1) != changed.end();
      if (!any_changed || iter + 1 == options_.max_iterations) break;
      for (std::size_t c = 0; c < centres->size(); ++c) {
        const std::uint32_t* b = (*bounds)[c];
        const std::uint32_t* e = (*bounds)[c + 1];
        if (e > b) (*centres)[c] = Majority(data_, b, e, PartsFor(static_cast<std::size_t>(e - b)));
      }
    }
    // Drop empty clusters.
    std::vector<OrbDescriptor> kept;
    std::vector<std::uint32_t*> kept_bounds;
    for (std::size_t c = 0; c < centres->size(); ++c) {
      if ((*bounds)[c + 1] > (*bounds)[c]) {
        kept.push_back((*centres)[c]);
        kept_bounds.push_back((*bounds)[c]);
      }
    }
    kept_bounds.push_back(end);
    *centres = std::move(kept);
    *bounds = std::move(kept_bounds);
  }

  // Greedy k-means++ (as in scikit-learn): each new centre is the best of a few D^2-weighted
  // draws, which rarely puts two seeds into one tight cluster.
  void SeedPlusPlus(const std::uint32_t* begin, std::size_t n, std::size_t k, Rng* rng,
                    std::vector<OrbDescriptor>* centres) {
    const int trials = 2 + static_cast<int>(std::log(static_cast<double>(k)));
    centres->clear();
    centres->push_back(*data_[begin[rng->Uniform(n)]]);
    const std::size_t parts = PartsFor(n);
    std::vector<double> min_d2(n), trial_d2(n), best_d2(n), part_potential(parts);
    ForParts(parts, n, [&](std::size_t, std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) {
        const double d = HammingDistance(*data_[begin[i]], centres->back());
        min_d2[i] = d * d;
      }
    });
    while (centres->size() < k) {
      double total = 0.0;
      for (double v : min_d2) total += v;
      if (total <= 0.0) break;  // all remaining points coincide with a centre
      double best_potential = -1.0;
      std::size_t best_pick = 0;
      for (int t = 0; t < trials; ++t) {
        const std::size_t pick = SampleD2(min_d2, total, rng);
        const OrbDescriptor& c = *data_[begin[pick]];
        ForParts(parts, n, [&](std::size_t p, std::size_t b, std::size_t e) {
          double sum = 0.0;
          for (std::size_t i = b; i < e; ++i) {
            const double d = HammingDistance(*data_[begin[i]], c);
            trial_d2[i] = std::min(min_d2[i], d * d);
            sum += trial_d2[i];
          }
          part_potential[p] = sum;
        });
        double potential = 0.0;
        for (double v : part_potential) potential += v;
        if (best_potential < 0.0 || potential < best_potential) {
          best_potential = potential;
          best_pick = pick;
          best_d2.swap(trial_d2);
        }
      }
      centres->push_back(*data_[begin[best_pick]]);
      min_d2.swap(best_d2);
    }
  }

  std::size_t PartsFor(std::size_t n) const {
    return n >= kMinParallelDescriptors ? static_cast<std::size_t>(std::max(options_.threads, 1)) : 1;
  }

  static std::size_t SampleD2(const std::vector<double>& d2, double total, Rng* rng) {
    double target = rng->Unit() * total;
    for (std::size_t i = 0; i < d2.size(); ++i) {
      target -= d2[i];
      if (target <= 0.0 && d2[i] > 0.0) return i;
    }
    for (std::size_t i = d2.size(); i-- > 0;) {
      if (d2[i] > 0.0) return i;
    }
    return 0;
  }

  // Stable counting sort of the index range by cluster; `assign` is permuted alongside.
  void PartitionByCluster(std::uint32_t* begin, std::vector<std::uint16_t>* assign,
                          std::size_t num_clusters, std::vector<std::uint32_t*>* bounds) {
    const std::size_t n = assign->size();
    std::vector<std::size_t> start(num_clusters + 1, 0);
    for (std::uint16_t a : *assign) ++start[a + 1];
    for (std::size_t c = 0; c < num_clusters; ++c) start[c + 1] += start[c];
    bounds->clear();
    for (std::size_t c = 0; c <= num_clusters; ++c) bounds->push_back(begin + start[c]);
    std::vector<std::uint32_t> sorted(n);
    std::vector<std::uint16_t> sorted_assign(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t pos = start[(*assign)[i]]++;
      sorted[pos] = begin[i];
      sorted_assign[pos] = (*assign)[i];
    }
    std::copy(sorted.begin(), sorted.end(), begin);
    *assign = std::move(sorted_assign);
  }

  // idf(word) = ln(N / n_word) over the training images (all descriptors, not the subsample).
  void ComputeIdf(const std::vector<std::vector<OrbDescriptor>>& images, Vocabulary* vocab) {
    std::vector<std::uint32_t> images_with_word(vocab->num_words(), 0);
    std::vector<std::uint32_t> last_image(vocab->num_words(), 0xffffffffu);
    for (std::size_t im = 0; im < images.size(); ++im) {
      for (const auto& d : images[im]) {
        const WordId w = vocab->Transform(d);
        if (last_image[w] != im) {
          last_image[w] = static_cast<std::uint32_t>(im);
          ++images_with_word[w];
        }
      }
      Report("weighting", static_cast<double>(im + 1) / images.size());
    }
    const double num_images = static_cast<double>(images.size());
    for (WordId w = 0; w < vocab->num_words(); ++w) {
      const double n = std::max<std::uint32_t>(images_with_word[w], 1);
      vocab->nodes_[vocab->words_[w]].weight = static_cast<float>(std::log(num_images / n));
    }
  }

  VocabularyOptions options_;
  TrainingProgressCallback progress_;
  std::vector<const OrbDescriptor*> data_;
  std::vector<Vocabulary::Node> nodes_;
  std::size_t done_ = 0;
  double last_reported_ = -1.0;
  std::string last_stage_;
};

Vocabulary Vocabulary::Train(const std::vector<std::vector<OrbDescriptor>>& images,
                             const VocabularyOptions& options,
                             const TrainingProgressCallback& progress) {
  VocabularyTrainer trainer(options, progress);
  return trainer.Run(images);
}

}  // namespace ccm
