// Vocabulary: training recovers synthetic clusters, determinism, TF-IDF/L1 properties,
// direct index, binary file round trip and rejection of damaged files.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include "slam_core/place_recognition/vocabulary.h"
#include "slam_core/place_recognition/vocabulary_io.h"

namespace ccm {
namespace {

OrbDescriptor RandomDescriptor(std::mt19937_64* rng) {
  OrbDescriptor d;
  for (auto& b : d) b = static_cast<uint8_t>((*rng)() & 0xff);
  return d;
}

OrbDescriptor FlipBits(OrbDescriptor d, int flips, std::mt19937_64* rng) {
  for (int i = 0; i < flips; ++i) {
    const int bit = static_cast<int>((*rng)() % 256);
    d[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
  }
  return d;
}

// `clusters` centres, each image holds a few noisy members of a few clusters.
struct ClusteredData {
  std::vector<OrbDescriptor> centres;
  std::vector<std::vector<OrbDescriptor>> images;
  std::vector<std::vector<int>> labels;
};

ClusteredData MakeClusters(int clusters, int images, int per_image, int flips, uint64_t seed) {
  std::mt19937_64 rng(seed);
  ClusteredData data;
  for (int c = 0; c < clusters; ++c) data.centres.push_back(RandomDescriptor(&rng));
  for (int i = 0; i < images; ++i) {
    data.images.emplace_back();
    data.labels.emplace_back();
    for (int j = 0; j < per_image; ++j) {
      const int c = static_cast<int>(rng() % clusters);
      data.images.back().push_back(FlipBits(data.centres[c], flips, &rng));
      data.labels.back().push_back(c);
    }
  }
  return data;
}

TEST(VocabularyTest, OptionsValidate) {
  VocabularyOptions o;
  EXPECT_EQ(o.Validate(), "");
  o.branching = 1;
  EXPECT_NE(o.Validate(), "");
  o = VocabularyOptions();
  o.levels = 0;
  EXPECT_NE(o.Validate(), "");
}

TEST(VocabularyTest, OneLevelRecoversClusters) {
  const ClusteredData data = MakeClusters(8, 60, 40, 12, 7);
  VocabularyOptions options;
  options.branching = 8;
  options.levels = 1;
  const Vocabulary vocab = Vocabulary::Train(data.images, options);
  ASSERT_EQ(vocab.num_words(), 8u);
  // Every member of a cluster maps to one word, and different clusters to different words.
  std::vector<std::set<WordId>> words_of_cluster(8);
  for (size_t i = 0; i < data.images.size(); ++i) {
    for (size_t j = 0; j < data.images[i].size(); ++j) {
      words_of_cluster[data.labels[i][j]].insert(vocab.Transform(data.images[i][j]));
    }
  }
  std::set<WordId> all;
  for (const auto& w : words_of_cluster) {
    ASSERT_EQ(w.size(), 1u);
    all.insert(*w.begin());
  }
  EXPECT_EQ(all.size(), 8u);
  // Centres are the majority of their members: close to the true centre.
  for (int c = 0; c < 8; ++c) {
    const WordId w = *words_of_cluster[c].begin();
    EXPECT_LE(HammingDistance(vocab.nodes()[vocab.WordNode(w)].descriptor, data.centres[c]), 3);
  }
}

TEST(VocabularyTest, DeterministicAndProgressReported) {
  const ClusteredData data = MakeClusters(30, 50, 60, 20, 3);
  VocabularyOptions options;
  options.branching = 4;
  options.levels = 3;
  options.seed = 11;
  std::vector<TrainingProgress> progress;
  const Vocabulary a = Vocabulary::Train(data.images, options,
                                         [&](const TrainingProgress& p) { progress.push_back(p); });
  const Vocabulary b = Vocabulary::Train(data.images, options);
  EXPECT_EQ(SerializeVocabulary(a), SerializeVocabulary(b));
  ASSERT_FALSE(progress.empty());
  EXPECT_EQ(progress.back().stage, "weighting");
  EXPECT_DOUBLE_EQ(progress.back().fraction, 1.0);
  for (const auto& n : a.nodes()) EXPECT_LE(n.depth, 3u);
  // Subsampling still yields a valid vocabulary.
  options.max_descriptors = 500;
  const Vocabulary c = Vocabulary::Train(data.images, options);
  EXPECT_GT(c.num_words(), 10u);
}

// Big nodes split their passes over threads (byte histograms for the majority): the tree must
// be the one of a single thread, and each word's centre the bitwise majority of its members.
TEST(VocabularyTest, ThreadsGiveTheSameTreeAndCentresAreMajorities) {
  const ClusteredData data = MakeClusters(6, 200, 60, 20, 9);  // 12,000 descriptors, ~2,000 per cluster
  VocabularyOptions options;
  options.branching = 6;
  options.levels = 1;
  const Vocabulary one = Vocabulary::Train(data.images, options);
  options.threads = 3;
  const Vocabulary three = Vocabulary::Train(data.images, options);
  EXPECT_EQ(SerializeVocabulary(one), SerializeVocabulary(three));
  ASSERT_EQ(one.num_words(), 6u);
  std::vector<std::array<int, 256>> ones(6, std::array<int, 256>{});
  std::vector<int> members(6, 0);
  for (const auto& image : data.images) {
    for (const auto& d : image) {
      const WordId w = one.Transform(d);
      ++members[w];
      for (int bit = 0; bit < 256; ++bit) ones[w][bit] += (d[bit / 8] >> (7 - bit % 8)) & 1;
    }
  }
  for (WordId w = 0; w < 6; ++w) {
    ASSERT_GT(members[w], 1000);
    OrbDescriptor majority{};
    for (int bit = 0; bit < 256; ++bit) {
      if (2 * ones[w][bit] > members[w]) majority[bit / 8] |= static_cast<uint8_t>(1u << (7 - bit % 8));
    }
    EXPECT_EQ(one.nodes()[one.WordNode(w)].descriptor, majority) << "word " << w;
  }
  // A deeper tree too (its root's passes are split, the smaller nodes below are not).
  options.levels = 3;
  options.threads = 1;
  const Vocabulary deep_one = Vocabulary::Train(data.images, options);
  options.threads = 2;
  EXPECT_EQ(SerializeVocabulary(deep_one), SerializeVocabulary(Vocabulary::Train(data.images, options)));
  options.threads = 0;
  EXPECT_NE(options.Validate(), "");
}

TEST(VocabularyTest, TfIdfAndL1Score) {
  const ClusteredData data = MakeClusters(40, 80, 50, 10, 5);
  VocabularyOptions options;
  options.branching = 6;
  options.levels = 3;
  const Vocabulary vocab = Vocabulary::Train(data.images, options);
  BowVector a, b, c;
  vocab.Transform(data.images[0], &a);
  vocab.Transform(data.images[0], &b);
  double sum = 0;
  for (const auto& e : a.entries) sum += e.second;
  EXPECT_NEAR(sum, 1.0, 1e-5);
  for (size_t i = 1; i < a.entries.size(); ++i) EXPECT_LT(a.entries[i - 1].first, a.entries[i].first);
  EXPECT_NEAR(ScoreL1(a, b), 1.0, 1e-6);
  // Disjoint word sets score 0; overlapping ones in between.
  BowVector x, y;
  x.entries = {{1, 0.5f}, {3, 0.5f}};
  y.entries = {{2, 0.25f}, {4, 0.75f}};
  EXPECT_DOUBLE_EQ(ScoreL1(x, y), 0.0);
  y.entries = {{3, 0.5f}, {4, 0.5f}};
  EXPECT_NEAR(ScoreL1(x, y), 0.5, 1e-6);
  vocab.Transform(data.images[1], &c);
  const double s = ScoreL1(a, c);
  EXPECT_GT(s, 0.0);
  EXPECT_LT(s, 1.0);
  EXPECT_DOUBLE_EQ(ScoreL1(a, c), ScoreL1(c, a));
}

TEST(VocabularyTest, DirectIndexGroupsFeaturesByNode) {
  const ClusteredData data = MakeClusters(40, 40, 80, 10, 9);
  VocabularyOptions options;
  options.branching = 5;
  options.levels = 4;
  const Vocabulary vocab = Vocabulary::Train(data.images, options);
  BowVector bow;
  FeatureVector fv;
  vocab.Transform(data.images[2], &bow, &fv, 2);
  size_t total = 0;
  for (const auto& [node, features] : fv.nodes) {
    EXPECT_LE(vocab.nodes()[node].depth, 2u);
    for (int f : features) {
      NodeId n = 0;
      vocab.Transform(data.images[2][f], &n, 2);
      EXPECT_EQ(n, node);
    }
    total += features.size();
  }
  EXPECT_EQ(total, data.images[2].size());
  std::vector<std::vector<int>> ga, gb;
  CommonNodeGroups(fv, fv, &ga, &gb);
  EXPECT_EQ(ga.size(), fv.size());
}

TEST(VocabularyIoTest, RoundTripAndCorruption) {
  const ClusteredData data = MakeClusters(30, 40, 50, 15, 13);
  VocabularyOptions options;
  options.branching = 5;
  options.levels = 3;
  const Vocabulary vocab = Vocabulary::Train(data.images, options);
  const std::string path = ::testing::TempDir() + "/vocab_roundtrip.ccmvoc";
  ASSERT_EQ(SaveVocabularyFile(vocab, path), "");
  std::string error;
  auto loaded = LoadVocabularyFile(path, &error);
  ASSERT_TRUE(loaded) << error;
  EXPECT_EQ(SerializeVocabulary(*loaded), SerializeVocabulary(vocab));
  EXPECT_EQ(loaded->num_words(), vocab.num_words());
  BowVector a, b;
  vocab.Transform(data.images[3], &a);
  loaded->Transform(data.images[3], &b);
  EXPECT_EQ(a.entries, b.entries);

  std::vector<uint8_t> bytes = SerializeVocabulary(vocab);
  std::vector<uint8_t> bad = bytes;
  bad[bytes.size() / 2] ^= 0x10;
  EXPECT_FALSE(DeserializeVocabulary(bad.data(), bad.size(), &error));
  EXPECT_NE(error.find("checksum"), std::string::npos) << error;
  EXPECT_FALSE(DeserializeVocabulary(bytes.data(), bytes.size() - 5, &error));
  EXPECT_NE(error.find("size mismatch"), std::string::npos) << error;
  bad = bytes;
  bad[0] = 'X';
  EXPECT_FALSE(DeserializeVocabulary(bad.data(), bad.size(), &error));
  EXPECT_NE(error.find("magic"), std::string::npos) << error;
  bad = bytes;
  bad[8] = 9;  // version
  EXPECT_FALSE(DeserializeVocabulary(bad.data(), bad.size(), &error));
  EXPECT_NE(error.find("version"), std::string::npos) << error;
  EXPECT_FALSE(LoadVocabularyFile(path + ".missing", &error));
  EXPECT_NE(error.find("cannot open"), std::string::npos);
  std::remove(path.c_str());
}

TEST(VocabularyIoTest, ImportsDbow2Text) {
  // k=2, L=2: two inner nodes with two leaves each (ORB-SLAM's ORBvoc.txt layout).
  std::string text = "2 2 0 0\n";
  auto line = [](int parent, int leaf, int fill, double weight) {
    std::string l = std::to_string(parent) + " " + std::to_string(leaf);
    for (int i = 0; i < 32; ++i) l += " " + std::to_string(fill);
    return l + " " + std::to_string(weight) + "\n";
  };
  text += line(0, 0, 0, 0) + line(0, 0, 255, 0);
  text += line(1, 1, 0, 1.5) + line(1, 1, 15, 2.5) + line(2, 1, 240, 3.5) + line(2, 1, 255, 4.5);
  std::istringstream in(text);
  std::string error;
  auto vocab = ImportDbow2TextVocabulary(in, &error);
  ASSERT_TRUE(vocab) << error;
  EXPECT_EQ(vocab->num_words(), 4u);
  EXPECT_EQ(vocab->branching(), 2);
  OrbDescriptor d;
  d.fill(255);
  const WordId w = vocab->Transform(d);
  EXPECT_EQ(w, 3u);
  EXPECT_FLOAT_EQ(vocab->WordWeight(w), 4.5f);
  d.fill(14);
  EXPECT_EQ(vocab->Transform(d), 1u);
  // Unsupported scoring and broken lines are reported.
  std::istringstream bad_scoring("10 6 1 0\n");
  EXPECT_FALSE(ImportDbow2TextVocabulary(bad_scoring, &error));
  EXPECT_NE(error.find("scoring"), std::string::npos);
  std::istringstream truncated("2 2 0 0\n0 0 1 2 3\n");
  EXPECT_FALSE(ImportDbow2TextVocabulary(truncated, &error));
  EXPECT_NE(error.find("line 2"), std::string::npos) << error;
}

}  // namespace
}  // namespace ccm
