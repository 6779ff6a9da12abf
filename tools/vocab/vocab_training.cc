#include "tools/vocab/vocab_training.h"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <thread>

#ifdef CCM_VOCAB_WITH_SIM
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"
#endif

namespace ccm::vocab {

using DescriptorSets = std::vector<std::vector<OrbDescriptor>>;

int ThreadsOrAllCores(int threads) {
  return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

std::string CollectOptions::Validate() const {
  if (max_images < 0) return "max_images must be >= 0";
  if (threads < 0) return "threads must be >= 0";
  return orb.Validate();
}

std::string CollectDescriptors(FrameSource* source, const CollectOptions& options, DescriptorSets* images,
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

ImagePlan PlanImages(const std::vector<std::int64_t>& dataset_frames, bool have_scenarios,
                     std::int64_t max_images) {
  ImagePlan plan;
  plan.dataset_images.assign(dataset_frames.size(), 0);
  if (max_images <= 0) {
    for (std::size_t i = 0; i < dataset_frames.size(); ++i) plan.dataset_images[i] = dataset_frames[i];
    plan.sim_images = have_scenarios ? -1 : 0;
    return plan;
  }
  std::vector<bool> open(dataset_frames.size(), true);
  std::int64_t open_count = static_cast<std::int64_t>(dataset_frames.size()) + (have_scenarios ? 1 : 0);
  std::int64_t remaining = max_images;
  // Short datasets give all their frames; their unused share goes to the others.
  for (bool changed = true; changed && open_count > 0;) {
    changed = false;
    const std::int64_t share = remaining / open_count;
    for (std::size_t i = 0; i < dataset_frames.size(); ++i) {
      if (!open[i] || dataset_frames[i] > share) continue;
      plan.dataset_images[i] = std::max<std::int64_t>(dataset_frames[i], 0);
      remaining -= plan.dataset_images[i];
      open[i] = false;
      --open_count;
      changed = true;
    }
  }
  // At least one image each, so that no source silently falls out of a tiny budget.
  const std::int64_t share = open_count > 0 ? std::max<std::int64_t>(1, remaining / open_count) : 0;
  for (std::size_t i = 0; i < dataset_frames.size(); ++i) {
    if (open[i]) plan.dataset_images[i] = share;
  }
  plan.sim_images = have_scenarios ? share : 0;
  return plan;
}

namespace {

// Runs job(i) for i in [0, n) on `threads` threads; returns the first error in job order.
// After a failure the remaining jobs are skipped.
std::string RunJobs(std::size_t n, int threads, const std::function<std::string(std::size_t)>& job) {
  std::vector<std::string> errors(n);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  auto worker = [&] {
    for (std::size_t i = next++; i < n && !failed; i = next++) {
      errors[i] = job(i);
      if (!errors[i].empty()) failed = true;
    }
  };
  threads = ThreadsOrAllCores(threads);
  const std::size_t spawned = std::min<std::size_t>(static_cast<std::size_t>(threads), n);
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < spawned; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  for (const auto& e : errors) {
    if (!e.empty()) return e;
  }
  return {};
}

}  // namespace

#ifdef CCM_VOCAB_WITH_SIM
bool HaveSimulator() { return true; }

namespace {

// One job per scenario: scene set-up (textures) and every agent's frames.
struct SimJobs {
  std::vector<std::string> names;
  std::vector<sim::Scenario> scenarios;
  std::int64_t num_agents = 0;
};

std::string LoadScenarios(const std::vector<std::string>& names, SimJobs* jobs) {
  for (const auto& name : names) {
    std::string error;
    auto scenario = sim::LoadScenario(name, &error);
    if (!scenario) return "scenario " + name + ": " + error;
    jobs->num_agents += static_cast<std::int64_t>(scenario->agents.size());
    jobs->names.push_back(name);
    jobs->scenarios.push_back(std::move(*scenario));
  }
  return jobs->num_agents == 0 && !names.empty() ? "no simulated agents" : "";
}

std::string RunScenario(const sim::Scenario& scenario, const std::string& name, std::int64_t per_agent,
                        const CollectOptions& options, DescriptorSets* out, const std::function<void()>& tick) {
  std::string error;
  std::shared_ptr<const sim::Simulation> s = sim::Simulation::Create(scenario, &error);
  if (!s) return "scenario " + name + ": " + error;
  for (int a = 0; a < s->num_agents(); ++a) {
    const std::int64_t frames = s->NumFrames(a);
    const std::int64_t stride = per_agent > 0 ? std::max<std::int64_t>(1, frames / per_agent) : 1;
    // Start half a stride in so different strides do not all sample frame 0.
    sim::SimFrameSource source(s, a, stride / 2, stride, per_agent > 0 ? per_agent : -1);
    CollectOptions o = options;
    o.max_images = 0;
    error = CollectDescriptors(&source, o, out, [&tick](std::int64_t, std::int64_t) { tick(); });
    if (!error.empty()) return error;
  }
  return {};
}

}  // namespace
#else
bool HaveSimulator() { return false; }
#endif

std::string CollectTrainingDescriptors(const TrainingSources& sources, const CollectOptions& options,
                                       DescriptorSets* images, const ImageProgressFn& progress) {
  std::string error = options.Validate();
  if (!error.empty()) return error;
#ifdef CCM_VOCAB_WITH_SIM
  SimJobs sim_jobs;
  error = LoadScenarios(sources.scenarios, &sim_jobs);
  if (!error.empty()) return error;
#else
  if (!sources.scenarios.empty()) {
    return "this ccm_vocab was built without the simulator (configure with CCM_BUILD_TESTS=ON)";
  }
#endif
  std::vector<std::unique_ptr<FrameSource>> datasets;
  std::vector<std::int64_t> frames;
  for (const auto& path : sources.datasets) {
    IoStatus status;
    datasets.push_back(OpenDataset(path, sources.format, &status));
    if (!datasets.back()) return status.message();  // names the folder or file
    frames.push_back(datasets.back()->size());
  }
  const ImagePlan plan = PlanImages(frames, !sources.scenarios.empty(), options.max_images);
  std::int64_t planned = 0;
  for (std::int64_t n : plan.dataset_images) planned += n;
  std::int64_t per_agent = 0;
#ifdef CCM_VOCAB_WITH_SIM
  if (plan.sim_images > 0) per_agent = std::max<std::int64_t>(1, plan.sim_images / sim_jobs.num_agents);
  planned = plan.sim_images < 0 ? -1 : planned + per_agent * sim_jobs.num_agents;
#endif
  std::mutex progress_mutex;
  std::int64_t done = 0;
  auto tick = [&] {
    std::lock_guard<std::mutex> lock(progress_mutex);
    ++done;
    if (progress) progress(done, planned);
  };
  // Every job fills its own slot; the slots are joined in job order afterwards.
  std::vector<DescriptorSets> slots(datasets.size() + sources.scenarios.size());
  error = RunJobs(slots.size(), options.threads, [&](std::size_t i) -> std::string {
    if (i < datasets.size()) {
      CollectOptions o = options;
      o.max_images = plan.dataset_images[i];
      return CollectDescriptors(datasets[i].get(), o, &slots[i], [&tick](std::int64_t, std::int64_t) { tick(); });
    }
#ifdef CCM_VOCAB_WITH_SIM
    const std::size_t s = i - datasets.size();
    return RunScenario(sim_jobs.scenarios[s], sim_jobs.names[s], per_agent, options, &slots[i], tick);
#else
    return "no simulator";
#endif
  });
  if (!error.empty()) return error;
  for (auto& slot : slots) {
    for (auto& image : slot) images->push_back(std::move(image));
  }
  return {};
}

std::string CollectSimDescriptors(const std::vector<std::string>& scenarios, const CollectOptions& options,
                                  DescriptorSets* images, const ImageProgressFn& progress) {
  TrainingSources sources;
  sources.scenarios = scenarios;
  return CollectTrainingDescriptors(sources, options, images, progress);
}

}  // namespace ccm::vocab
