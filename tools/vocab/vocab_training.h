// Training-data collection for vocabularies: images from dataset folders and simulator scenes
// (when built with tests) -> OrbExtractor -> per-image descriptor sets, several sources at
// once. Used by the ccm_vocab CLI, the default vocabulary (default_vocabulary.h) and the
// place-recognition tests. No printing (progress goes through callbacks); worker threads only
// inside CollectTrainingDescriptors, whose result does not depend on their number.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/feature/orb_extractor.h"
#include "slam_core/io/dataset.h"
#include "slam_core/io/frame_source.h"
#include "slam_core/place_recognition/vocabulary.h"

namespace ccm::vocab {

/// Called after each image: images done, images planned (-1 if unknown). Called from one
/// thread at a time.
using ImageProgressFn = std::function<void(std::int64_t done, std::int64_t total)>;

/// `threads`, or all cores (at least 1) for 0: the meaning of the tools' --threads.
int ThreadsOrAllCores(int threads);

struct CollectOptions {
  OrbExtractorOptions orb;      ///< extractor settings (use the SLAM front end's)
  std::int64_t max_images = 0;  ///< images over all sources (see PlanImages); 0 = every image
  int threads = 1;              ///< worker threads rendering / extracting; 0 = all cores
  std::string Validate() const;
};

/// Reads up to options.max_images frames spread evenly over `source` and appends their
/// descriptors to *images. Empty string on success, else the source's error.
std::string CollectDescriptors(FrameSource* source, const CollectOptions& options,
                               std::vector<std::vector<OrbDescriptor>>* images,
                               const ImageProgressFn& progress = {});

/// True if this build can render simulator scenes (built together with tests/sim).
bool HaveSimulator();

/// Descriptors from simulator scenes: `max_images` split evenly over the scenarios' agents.
/// Scenario names are built-ins (hall3, disjoint2, repeated), generated (gen:SEED) or YAML paths.
std::string CollectSimDescriptors(const std::vector<std::string>& scenarios,
                                  const CollectOptions& options,
                                  std::vector<std::vector<OrbDescriptor>>* images,
                                  const ImageProgressFn& progress = {});

/// Training inputs used together: dataset folders and simulator scenarios.
struct TrainingSources {
  std::vector<std::string> datasets;            ///< EuRoC / TUM RGB-D / KITTI folders
  DatasetFormat format = DatasetFormat::kAuto;  ///< of every dataset folder
  std::vector<std::string> scenarios;           ///< simulator scenarios (one source together)
};

/// How many images each source gives. Sources: every dataset folder, and all scenarios together
/// (as one source, split evenly over their agents). `max_images` is split evenly over the
/// sources; a dataset with fewer frames than its share gives all of them and the rest is
/// shared by the others (repeatedly), so short real sequences are used whole and the
/// simulator takes what is left. max_images = 0: every frame of every source (sim: -1 = all).
struct ImagePlan {
  std::vector<std::int64_t> dataset_images;  ///< per dataset folder
  std::int64_t sim_images = 0;               ///< all scenarios together (0 without scenarios)
};
ImagePlan PlanImages(const std::vector<std::int64_t>& dataset_frames, bool have_scenarios,
                     std::int64_t max_images);

/// Descriptors from all sources per PlanImages, datasets first (in order), then the scenarios
/// (as CollectSimDescriptors). Rendering and ORB run on options.threads threads; the images
/// come out in the same order whatever the thread count. Empty string on success.
std::string CollectTrainingDescriptors(const TrainingSources& sources, const CollectOptions& options,
                                       std::vector<std::vector<OrbDescriptor>>* images,
                                       const ImageProgressFn& progress = {});

}  // namespace ccm::vocab
