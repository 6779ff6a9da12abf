#include "tools/vocab/vocab_training.h"

#include <algorithm>

#include "slam_core/place_recognition/vocabulary_io.h"

#ifdef CCM_VOCAB_WITH_SIM
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"
#endif

namespace ccm::vocab {

std::string CollectOptions::Validate() const {
  if (max_images < 0) return "max_images must be >= 0";
  return orb.Validate();
}

std::string CollectDescriptors(FrameSource* source, const CollectOptions& options,
                               std::vector<std::vector<OrbDescriptor>>* images,
                               const ImageProgressFn& progress) {
  OrbExtractor extractor(options.orb);
  const std::int64_t size = source->size();
  std::int64_t stride = 1;
  std::int64_t planned = size;
  if (options.max_images > 0 && size > options.max_images) {
    stride = size / options.max_images;
    planned = options.max_images;
  }
  std::int64_t index = 0, done = 0;
  while (auto frame = source->Next()) {
    if (index++ % stride != 0) continue;
    if (options.max_images > 0 && done >= options.max_images) break;
    FrameFeatures features = extractor.Extract(frame->image);
    if (!features.descriptors.empty()) images->push_back(std::move(features.descriptors));
    ++done;
    if (progress) progress(done, planned);
  }
  return source->error();
}

#ifdef CCM_VOCAB_WITH_SIM
bool HaveSimulator() { return true; }

std::string CollectSimDescriptors(const std::vector<std::string>& scenarios,
                                  const CollectOptions& options,
                                  std::vector<std::vector<OrbDescriptor>>* images,
                                  const ImageProgressFn& progress) {
  std::vector<std::shared_ptr<const sim::Simulation>> sims;
  std::int64_t num_agents = 0;
  for (const auto& name : scenarios) {
    std::string error;
    auto scenario = sim::LoadScenario(name, &error);
    if (!scenario) return "scenario " + name + ": " + error;
    std::shared_ptr<const sim::Simulation> s = sim::Simulation::Create(*scenario, &error);
    if (!s) return "scenario " + name + ": " + error;
    num_agents += s->num_agents();
    sims.push_back(std::move(s));
  }
  if (num_agents == 0) return "no simulated agents";
  const std::int64_t per_agent =
      options.max_images > 0 ? std::max<std::int64_t>(1, options.max_images / num_agents) : 0;
  const std::int64_t planned = per_agent > 0 ? per_agent * num_agents : 0;
  std::int64_t done_before = 0;
  for (const auto& s : sims) {
    for (int a = 0; a < s->num_agents(); ++a) {
      const std::int64_t frames = s->NumFrames(a);
      const std::int64_t stride = per_agent > 0 ? std::max<std::int64_t>(1, frames / per_agent) : 1;
      // Start half a stride in so different strides do not all sample frame 0.
      sim::SimFrameSource source(s, a, stride / 2, stride, per_agent > 0 ? per_agent : -1);
      CollectOptions o = options;
      o.max_images = 0;
      const std::string error = CollectDescriptors(&source, o, images, [&](std::int64_t d, std::int64_t) {
        if (progress) progress(done_before + d, planned > 0 ? planned : -1);
      });
      if (!error.empty()) return error;
      done_before += source.size();
    }
  }
  return {};
}
#else
bool HaveSimulator() { return false; }

std::string CollectSimDescriptors(const std::vector<std::string>&, const CollectOptions&,
                                  std::vector<std::vector<OrbDescriptor>>*, const ImageProgressFn&) {
  return "this ccm_vocab was built without the simulator (configure with CCM_BUILD_TESTS=ON)";
}
#endif

std::optional<Vocabulary> LoadOrTrainSimVocabulary(const std::string& cache_path,
                                                   const SimVocabularySpec& spec,
                                                   std::string* error) {
  std::string load_error;
  if (auto vocab = LoadVocabularyFile(cache_path, &load_error)) return vocab;
  std::vector<std::vector<OrbDescriptor>> images;
  CollectOptions collect;
  collect.max_images = spec.max_images;
  std::string problem = CollectSimDescriptors(spec.scenarios, collect, &images);
  if (!problem.empty()) {
    if (error) *error = problem;
    return std::nullopt;
  }
  Vocabulary vocab = Vocabulary::Train(images, spec.vocabulary);
  problem = SaveVocabularyFile(vocab, cache_path);
  if (!problem.empty()) {
    if (error) *error = problem;
    return std::nullopt;
  }
  return vocab;
}

}  // namespace ccm::vocab
