#include "tools/vocab/default_vocabulary.h"

#include <filesystem>

#include "slam_core/place_recognition/vocabulary_io.h"

namespace ccm::vocab {
namespace {

// Measured in docs/place-recognition.md ("The default vocabulary").
constexpr int kGeneratedScenes = 40;
constexpr std::int64_t kMaxImages = 1600;
constexpr int kBranching = 10;
constexpr int kLevels = 5;

}  // namespace

DefaultVocabularySpec MakeDefaultVocabularySpec(const std::string& shared_data_dir) {
  DefaultVocabularySpec spec;
  for (int i = 0; i < kGeneratedScenes; ++i) {
    spec.sources.scenarios.push_back("gen:" + std::to_string(kFirstTrainingSeed + i));
  }
  for (const char* name : {"hall3", "disjoint2", "repeated"}) spec.sources.scenarios.push_back(name);
  if (!shared_data_dir.empty()) {
    for (const char* name : kTrainingDatasets) {
      const std::filesystem::path dir = std::filesystem::path(shared_data_dir) / name;
      std::error_code ec;
      if (std::filesystem::is_directory(dir, ec)) spec.sources.datasets.push_back(dir.lexically_normal().string());
    }
  }
  spec.max_images = kMaxImages;
  spec.vocabulary.branching = kBranching;
  spec.vocabulary.levels = kLevels;
  return spec;
}

std::string DescribeAsCommand(const DefaultVocabularySpec& spec) {
  std::string cmd = "ccm_vocab train";
  for (const auto& d : spec.sources.datasets) cmd += " --dataset " + d;
  for (const auto& s : spec.sources.scenarios) cmd += " --sim " + s;
  cmd += " --k " + std::to_string(spec.vocabulary.branching) + " --levels " + std::to_string(spec.vocabulary.levels);
  cmd += " --max-images " + std::to_string(spec.max_images) + " --features " + std::to_string(spec.features);
  cmd += " --max-descriptors " + std::to_string(spec.vocabulary.max_descriptors);
  cmd += " --iterations " + std::to_string(spec.vocabulary.max_iterations);
  cmd += " --seed " + std::to_string(spec.vocabulary.seed);
  return cmd;
}

std::optional<Vocabulary> LoadOrTrainDefaultVocabulary(const std::string& cache_path,
                                                       const DefaultVocabularySpec& spec,
                                                       std::string* error, int threads) {
  std::string load_error;
  if (auto vocab = LoadVocabularyFile(cache_path, &load_error)) return vocab;
  std::vector<std::vector<OrbDescriptor>> images;
  CollectOptions collect;
  collect.max_images = spec.max_images;
  collect.orb.num_features = spec.features;
  collect.threads = threads;
  std::string problem = CollectTrainingDescriptors(spec.sources, collect, &images);
  if (problem.empty() && images.empty()) problem = "no training images";
  if (!problem.empty()) {
    if (error) *error = problem;
    return std::nullopt;
  }
  VocabularyOptions threaded = spec.vocabulary;  // same tree for any thread count
  threaded.threads = ThreadsOrAllCores(threads);
  Vocabulary vocab = Vocabulary::Train(images, threaded);
  problem = SaveVocabularyFile(vocab, cache_path);
  if (!problem.empty()) {
    if (error) *error = problem;
    return std::nullopt;
  }
  return vocab;
}

}  // namespace ccm::vocab
