// The default vocabulary (tools/vocab/default_vocabulary.h): its spec never trains on scenes
// the benchmarks or these tests evaluate on, it finds revisits on a generated scene it never
// saw (ground truth from the simulator), and the training-data split over several sources
// (PlanImages / CollectTrainingDescriptors) does what docs/place-recognition.md says.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "tests/sim/euroc_writer.h"
#include "tests/slam_core/place_recognition/retrieval_eval.h"
#include "tools/vocab/default_vocabulary.h"

namespace ccm::test {
namespace {

// Held out: the recall test below and docs/place-recognition.md measure on gen:7001-7010.
constexpr std::uint64_t kHeldOutSeed = 7010;  // corridor, weak textures, 2 agents

TEST(DefaultVocabularyTest, SpecTrainsOnNoBenchmarkOrHeldOutSeed) {
  const vocab::DefaultVocabularySpec spec = vocab::MakeDefaultVocabularySpec("");
  EXPECT_TRUE(spec.sources.datasets.empty());
  int generated = 0;
  for (const auto& name : spec.sources.scenarios) {
    if (name.rfind("gen:", 0) != 0) continue;
    const std::uint64_t seed = std::stoull(name.substr(4));
    ++generated;
    // bench_fusion: 1-20 tuning, 1001-1040 held out; recall: 7001-7010.
    EXPECT_GE(seed, vocab::kFirstTrainingSeed) << name;
    EXPECT_FALSE(seed >= 7001 && seed <= 7010) << name;
  }
  EXPECT_GE(generated, 20);
  EXPECT_EQ(spec.vocabulary.levels, DefaultVocabulary().levels());
  EXPECT_EQ(spec.vocabulary.branching, DefaultVocabulary().branching());
}

TEST(DefaultVocabularyTest, RecallOnHeldOutGeneratedScene) {
  std::vector<SimKeyframe> kfs;
  const std::string scene = "gen:" + std::to_string(kHeldOutSeed);
  ASSERT_EQ(MakeScenarioKeyframes(scene, DefaultVocabulary(), 0.5, 0, &kfs), "");
  RetrievalOptions options;  // revisit < 0.5 m, hit < 1 m, 30 deg, own agent >= 10 s apart
  options.verify = true;
  const RetrievalStats st = ScoreRetrieval(kfs, DefaultVocabulary().num_words(), options);
  std::printf("%s: %d keyframes, %d revisit queries, top-1 %.3f, top-3 %.3f, verified %d queries "
              "(%d right, %d wrong)\n", scene.c_str(), st.keyframes, st.queries, st.RecallTop1(),
              st.RecallTopK(), st.queries_verified, st.verified_correct, st.verified_wrong);
  EXPECT_GE(st.queries, 100);
  EXPECT_GE(st.RecallTop1(), 0.90);
  EXPECT_GE(st.RecallTopK(), 0.94);
  EXPECT_GE(st.queries_verified, 0.90 * st.queries);
  EXPECT_EQ(st.verified_wrong, 0);
}

TEST(DefaultVocabularyTest, PlanSharesImagesOverSources) {
  // One source: all of max_images (the old single-source behaviour).
  vocab::ImagePlan p = vocab::PlanImages({1000}, false, 300);
  EXPECT_EQ(p.dataset_images, std::vector<std::int64_t>({300}));
  p = vocab::PlanImages({}, true, 240);
  EXPECT_EQ(p.sim_images, 240);
  // Short datasets give every frame, the simulator takes the rest.
  p = vocab::PlanImages({160, 150}, true, 1200);
  EXPECT_EQ(p.dataset_images, std::vector<std::int64_t>({160, 150}));
  EXPECT_EQ(p.sim_images, 890);
  // Evenly when every source is long enough; a short one frees its share repeatedly.
  p = vocab::PlanImages({5000, 100, 5000}, true, 1000);
  EXPECT_EQ(p.dataset_images, std::vector<std::int64_t>({300, 100, 300}));
  EXPECT_EQ(p.sim_images, 300);
  // 0 = everything.
  p = vocab::PlanImages({10, 20}, true, 0);
  EXPECT_EQ(p.dataset_images, std::vector<std::int64_t>({10, 20}));
  EXPECT_EQ(p.sim_images, -1);
}

TEST(DefaultVocabularyTest, CollectsDatasetAndScenesTogetherWhateverTheThreads) {
  // A 12-frame EuRoC folder written from hall3's first agent, plus the hall3 scene.
  std::string error;
  auto scenario = sim::LoadScenario("hall3", &error);
  ASSERT_TRUE(scenario) << error;
  auto s = sim::Simulation::Create(*scenario, &error);
  ASSERT_TRUE(s) << error;
  const std::string dir = (std::filesystem::temp_directory_path() / "ccm_vocab_sources_test").string();
  std::filesystem::remove_all(dir);
  ASSERT_EQ(sim::WriteEurocAgent(*s, 0, dir, 12), "");
  vocab::TrainingSources sources;
  sources.datasets = {dir + "/" + s->agent_name(0)};
  sources.scenarios = {"hall3"};
  vocab::CollectOptions options;
  options.max_images = 40;  // dataset 12 of a share of 20, simulator 28 -> 9 per agent
  options.threads = 1;
  std::vector<std::vector<OrbDescriptor>> one, three;
  ASSERT_EQ(vocab::CollectTrainingDescriptors(sources, options, &one), "");
  options.threads = 3;
  ASSERT_EQ(vocab::CollectTrainingDescriptors(sources, options, &three), "");
  std::filesystem::remove_all(dir);
  ASSERT_EQ(one.size(), 12u + 27u);
  EXPECT_TRUE(one == three);
  // Datasets come first: image 0 is frame 0 of agent 0 (PNG is lossless).
  OrbExtractor extractor(options.orb);
  EXPECT_TRUE(one[0] == extractor.Extract(s->RenderFrame(0, 0)).descriptors);
  // A missing folder is an error naming it, not an empty contribution.
  sources.datasets = {dir + "/missing"};
  EXPECT_NE(vocab::CollectTrainingDescriptors(sources, options, &one).find("missing"), std::string::npos);
}

}  // namespace
}  // namespace ccm::test
