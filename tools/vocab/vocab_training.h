// Training-data collection for vocabularies: images from a FrameSource (datasets, or the
// simulator when built with tests) -> OrbExtractor -> per-image descriptor sets, and the
// simulator vocabulary used by tests and demos (trained once, cached as a file).
// Used by the ccm_vocab CLI and by place_recognition_test; single-threaded, no printing
// (progress goes through callbacks).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/feature/orb_extractor.h"
#include "slam_core/io/frame_source.h"
#include "slam_core/place_recognition/vocabulary.h"

namespace ccm::vocab {

/// Called after each image: images done, images planned.
using ImageProgressFn = std::function<void(std::int64_t done, std::int64_t total)>;

struct CollectOptions {
  OrbExtractorOptions orb;      ///< extractor settings (use the SLAM front end's)
  std::int64_t max_images = 0;  ///< images taken evenly over the source; 0 = every image
  std::string Validate() const;
};

/// Reads up to options.max_images frames spread evenly over `source` and appends their
/// descriptors to *images. Empty string on success, else the source's error.
std::string CollectDescriptors(FrameSource* source, const CollectOptions& options,
                               std::vector<std::vector<OrbDescriptor>>* images,
                               const ImageProgressFn& progress = {});

/// True if this build can render simulator scenes (built together with tests/sim).
bool HaveSimulator();

/// Descriptors from simulator scenes: `max_images` split evenly over the scenarios and their
/// agents. Scenario names are built-ins (hall3, disjoint2, repeated) or YAML paths.
std::string CollectSimDescriptors(const std::vector<std::string>& scenarios,
                                  const CollectOptions& options,
                                  std::vector<std::vector<OrbDescriptor>>* images,
                                  const ImageProgressFn& progress = {});

/// The vocabulary tests and demos use: k=10, L=5 from ~240 frames of all built-in scenes.
struct SimVocabularySpec {
  std::vector<std::string> scenarios = {"hall3", "disjoint2", "repeated"};
  std::int64_t max_images = 240;
  VocabularyOptions vocabulary = [] {
    VocabularyOptions o;
    o.levels = 5;
    return o;
  }();
};

/// Loads `cache_path` if it holds a valid vocabulary, else trains one from the simulator
/// and saves it there (atomically). nullopt + *error if neither works.
std::optional<Vocabulary> LoadOrTrainSimVocabulary(const std::string& cache_path,
                                                   const SimVocabularySpec& spec,
                                                   std::string* error);

}  // namespace ccm::vocab
