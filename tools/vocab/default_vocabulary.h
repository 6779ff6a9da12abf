// The default vocabulary of ccm_server, ccm_replay, the agent's relocalization, the demo, the
// Debian package and the tests: a general one for scenes and cameras nobody tuned for, trained
// at build time (`ccm_vocab train-default`, tools/vocab/CMakeLists.txt) from many generated
// simulator scenes and the built-in ones. Real images are left out on purpose: the build must
// not depend on data beside the repository, and the real excerpts the tests run on must stay
// unseen (training on them lifted their own recall, not that of other real data).
// One spec serves the build step and LoadOrTrainDefaultVocabulary, so both write the same
// file. Choice of k/L and image counts: docs/place-recognition.md, "The default vocabulary".
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/place_recognition/vocabulary.h"
#include "tools/vocab/vocab_training.h"

namespace ccm::vocab {

/// Generated training scenes are gen:kFirstTrainingSeed ... ; benchmarks use seeds 1-20
/// (tuning) and 1001-1040 (held out), the recall measurements 7001-7010: never trained on.
inline constexpr std::uint64_t kFirstTrainingSeed = 5001;
/// Real excerpts an ablation may add (`ccm_vocab train-default --shared-data DIR`); the
/// build's default uses none (docs/place-recognition.md).
inline constexpr const char* kTrainingDatasets[] = {"kitti07_first160", "ntsd150_euroc"};

struct DefaultVocabularySpec {
  TrainingSources sources;
  std::int64_t max_images = 0;  ///< split over the sources as PlanImages does
  int features = 1000;          ///< ORB per image (the front end's default)
  VocabularyOptions vocabulary;
};

/// The build's spec: the generated scenes and the built-ins; with `shared_data_dir`, also those
/// of kTrainingDatasets that exist there (ablations only, not the default).
DefaultVocabularySpec MakeDefaultVocabularySpec(const std::string& shared_data_dir = "");

/// The same spec as a `ccm_vocab train` command line (for the docs and ablations).
std::string DescribeAsCommand(const DefaultVocabularySpec& spec);

/// Loads `cache_path` if it holds a valid vocabulary, else trains one from `spec` (threads: as
/// CollectOptions; the file does not depend on it) and saves it there atomically.
/// nullopt + *error if neither works.
std::optional<Vocabulary> LoadOrTrainDefaultVocabulary(const std::string& cache_path,
                                                       const DefaultVocabularySpec& spec,
                                                       std::string* error, int threads = 0);

}  // namespace ccm::vocab
