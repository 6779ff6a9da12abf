// ccm_vocab: train, inspect and try out bag-of-words vocabularies.
//   ccm_vocab train --dataset DIR [--format auto|euroc|tum|kitti] --out FILE [--k 10 --levels 6]
//   ccm_vocab train --sim hall3 --sim repeated --out FILE --levels 5 --max-images 300
//   ccm_vocab train --dataset A --dataset B --sim gen:5001 --sim gen:5002 --out FILE
//   ccm_vocab train-default --out FILE   (the build's default; --shared-data DIR for ablations)
//   ccm_vocab info FILE
//   ccm_vocab query --vocab FILE --images a.png b.png c.png
//   ccm_vocab convert --dbow2-text ORBvoc.txt --out orb.ccmvoc
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "slam_core/common/stopwatch.h"
#include "slam_core/io/dataset.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "tools/vocab/default_vocabulary.h"
#include "tools/vocab/vocab_training.h"

namespace {

using Clock = std::chrono::steady_clock;
// At most two progress lines per second (and the last one), so logs stay short.
class ProgressLine {
 public:
  bool Due(bool last) {
    const auto now = Clock::now();
    if (!last && now - last_ < std::chrono::milliseconds(500)) return false;
    last_ = now;
    return true;
  }

 private:
  Clock::time_point last_{};
};

struct TrainArgs {
  std::vector<std::string> datasets, sim;
  std::string format = "auto", out;
  ccm::VocabularyOptions vocab;
  std::int64_t max_images = 2000;
  int features = 1000;
  int threads = 0;
};

// Extracts the training descriptors from all sources; empty string or error.
std::string CollectImages(const ccm::vocab::TrainingSources& sources, const ccm::vocab::CollectOptions& collect,
                          std::vector<std::vector<ccm::OrbDescriptor>>* images) {
  ProgressLine line;
  auto progress = [&line](std::int64_t done, std::int64_t total) {
    if (!line.Due(done == total)) return;
    std::fprintf(stderr, "\rextracting ORB: %lld / %lld images", static_cast<long long>(done),
                 static_cast<long long>(total));
  };
  const std::string error = ccm::vocab::CollectTrainingDescriptors(sources, collect, images, progress);
  std::fprintf(stderr, "\n");
  return error;
}

// Collects, trains and saves; prints progress and timings to stderr.
int TrainAndSave(const ccm::vocab::TrainingSources& sources, const ccm::vocab::CollectOptions& collect,
                 const ccm::VocabularyOptions& options, const std::string& out) {
  std::vector<std::vector<ccm::OrbDescriptor>> images;
  const auto t0 = Clock::now();
  std::string error = CollectImages(sources, collect, &images);
  if (!error.empty()) {
    std::fprintf(stderr, "train: %s\n", error.c_str());
    return 1;
  }
  std::size_t total = 0;
  for (const auto& im : images) total += im.size();
  std::fprintf(stderr, "%zu images, %zu descriptors in %.1f s\n", images.size(), total, ccm::SecondsSince(t0));
  if (images.empty()) return 1;
  const auto t1 = Clock::now();
  ProgressLine line;
  ccm::VocabularyOptions threaded = options;  // same tree for any thread count
  threaded.threads = ccm::vocab::ThreadsOrAllCores(collect.threads);
  const ccm::Vocabulary vocab =
      ccm::Vocabulary::Train(images, threaded, [&line](const ccm::TrainingProgress& p) {
        if (!line.Due(p.fraction >= 1.0)) return;
        std::fprintf(stderr, "\r%-10s %5.1f %%", p.stage.c_str(), 100.0 * p.fraction);
      });
  std::fprintf(stderr, "\ntrained k=%d L=%d: %zu words, %zu nodes in %.1f s\n", vocab.branching(),
               vocab.levels(), vocab.num_words(), vocab.num_nodes(), ccm::SecondsSince(t1));
  error = ccm::SaveVocabularyFile(vocab, out);
  if (!error.empty()) {
    std::fprintf(stderr, "train: %s\n", error.c_str());
    return 1;
  }
  std::printf("wrote %s\n", out.c_str());
  return 0;
}

int Train(const TrainArgs& args) {
  if (args.datasets.empty() && args.sim.empty()) {
    std::fprintf(stderr, "train: give at least one --dataset or --sim\n");
    return 2;
  }
  const std::string problem = args.vocab.Validate();
  if (!problem.empty()) {
    std::fprintf(stderr, "train: %s\n", problem.c_str());
    return 2;
  }
  ccm::vocab::TrainingSources sources;
  sources.datasets = args.datasets;
  sources.scenarios = args.sim;
  const auto format = ccm::ParseDatasetFormat(args.format);
  if (!format) {
    std::fprintf(stderr, "train: unknown --format %s (auto, euroc, tum, kitti)\n", args.format.c_str());
    return 1;
  }
  sources.format = *format;
  ccm::vocab::CollectOptions collect;
  collect.max_images = args.max_images;
  collect.orb.num_features = args.features;
  collect.threads = args.threads;
  return TrainAndSave(sources, collect, args.vocab, args.out);
}

// The build's default vocabulary (default_vocabulary.h): says which sources it uses.
int TrainDefault(const std::string& shared_data, const std::string& out, int threads) {
  const ccm::vocab::DefaultVocabularySpec spec = ccm::vocab::MakeDefaultVocabularySpec(shared_data);
  if (!shared_data.empty() && spec.sources.datasets.empty()) {
    std::fprintf(stderr, "default vocabulary: no real sequences under '%s': simulator scenes only\n",
                 shared_data.c_str());
  }
  std::fprintf(stderr, "default vocabulary: %zu simulator scenes, %zu real sequences; same as\n  %s\n",
               spec.sources.scenarios.size(), spec.sources.datasets.size(),
               ccm::vocab::DescribeAsCommand(spec).c_str());
  ccm::vocab::CollectOptions collect;
  collect.max_images = spec.max_images;
  collect.orb.num_features = spec.features;
  collect.threads = threads;
  return TrainAndSave(spec.sources, collect, spec.vocabulary, out);
}

int Convert(const std::string& in, const std::string& out) {
  std::string error;
  auto vocab = ccm::ImportDbow2TextFile(in, &error);
  if (!vocab) {
    std::fprintf(stderr, "convert: %s\n", error.c_str());
    return 1;
  }
  error = ccm::SaveVocabularyFile(*vocab, out);
  if (!error.empty()) {
    std::fprintf(stderr, "convert: %s\n", error.c_str());
    return 1;
  }
  std::printf("wrote %s (k=%d L=%d, %zu words)\n", out.c_str(), vocab->branching(), vocab->levels(),
              vocab->num_words());
  return 0;
}

int Info(const std::string& path) {
  const auto t0 = Clock::now();
  std::string error;
  auto vocab = ccm::LoadVocabularyFile(path, &error);
  const double load_s = ccm::SecondsSince(t0);
  if (!vocab) {
    std::fprintf(stderr, "info: %s\n", error.c_str());
    return 1;
  }
  std::map<std::uint32_t, std::size_t> words_per_depth;
  double min_w = 1e9, max_w = 0, sum_w = 0;
  for (const auto& n : vocab->nodes()) {
    if (n.word == ccm::Vocabulary::kNoWord) continue;
    ++words_per_depth[n.depth];
    min_w = std::min<double>(min_w, n.weight);
    max_w = std::max<double>(max_w, n.weight);
    sum_w += n.weight;
  }
  std::printf("file:        %s (%ju bytes, format v%u)\n", path.c_str(),
              static_cast<std::uintmax_t>(std::filesystem::file_size(path)), ccm::kVocabularyVersion);
  std::printf("branching k: %d\nlevels L:    %d\nweighting:   TF-IDF\nscoring:     L1\n",
              vocab->branching(), vocab->levels());
  std::printf("nodes:       %zu\nwords:       %zu\n", vocab->num_nodes(), vocab->num_words());
  for (const auto& [depth, n] : words_per_depth) std::printf("  words at depth %u: %zu\n", depth, n);
  std::printf("idf:         min %.3f  mean %.3f  max %.3f\n", min_w, sum_w / vocab->num_words(), max_w);
  std::printf("load time:   %.1f ms\n", 1e3 * load_s);
  return 0;
}

int Query(const std::string& vocab_path, const std::vector<std::string>& image_paths, int features) {
  std::string error;
  auto vocab = ccm::LoadVocabularyFile(vocab_path, &error);
  if (!vocab) {
    std::fprintf(stderr, "query: %s\n", error.c_str());
    return 1;
  }
  ccm::OrbExtractorOptions orb;
  orb.num_features = features;
  ccm::OrbExtractor extractor(orb);
  std::vector<ccm::BowVector> bows;
  for (const auto& p : image_paths) {
    cv::Mat image = cv::imread(p, cv::IMREAD_GRAYSCALE);
    if (image.empty()) {
      std::fprintf(stderr, "query: cannot read image %s\n", p.c_str());
      return 1;
    }
    const auto features_of = extractor.Extract(image);
    bows.emplace_back();
    vocab->Transform(features_of.descriptors, &bows.back());
    std::printf("[%zu] %s: %zu features, %zu words\n", bows.size() - 1, p.c_str(), features_of.size(),
                bows.back().size());
  }
  std::printf("L1 scores:\n      ");
  for (std::size_t j = 0; j < bows.size(); ++j) std::printf(" [%3zu]", j);
  std::printf("\n");
  for (std::size_t i = 0; i < bows.size(); ++i) {
    std::printf("[%3zu] ", i);
    for (std::size_t j = 0; j < bows.size(); ++j) std::printf(" %.3f", ccm::ScoreL1(bows[i], bows[j]));
    std::printf("\n");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ccm_vocab: train and inspect binary bag-of-words vocabularies"};
  app.require_subcommand(1);

  TrainArgs train;
  auto* t = app.add_subcommand("train", "train a vocabulary from a dataset or simulator scenes");
  t->add_option("--dataset", train.datasets, "dataset folder (EuRoC, TUM RGB-D, KITTI; repeatable)");
  t->add_option("--format", train.format, "auto, euroc, tum, kitti")->capture_default_str();
  t->add_option("--sim", train.sim,
                ccm::vocab::HaveSimulator() ? "simulator scenario (repeatable): hall3, disjoint2, repeated, gen:SEED or YAML"
                                            : "simulator scenario (not available in this build)");
  t->add_option("--out", train.out, "output vocabulary file")->required();
  t->add_option("--k", train.vocab.branching, "branching factor")->capture_default_str();
  t->add_option("--levels", train.vocab.levels, "tree depth L")->capture_default_str();
  t->add_option("--max-images", train.max_images,
                "images used (0 = all), split evenly over the sources: each --dataset folder and all "
                "--sim scenarios together (over their agents); a short dataset gives all its frames "
                "and leaves the rest to the others")
      ->capture_default_str();
  t->add_option("--max-descriptors", train.vocab.max_descriptors,
                "descriptors clustered (subsampled above this; 0 = all)")->capture_default_str();
  t->add_option("--iterations", train.vocab.max_iterations, "k-majority iterations per node")
      ->capture_default_str();
  t->add_option("--features", train.features, "ORB features per image")->capture_default_str();
  t->add_option("--seed", train.vocab.seed, "random seed")->capture_default_str();
  t->add_option("--threads", train.threads, "threads rendering, extracting ORB and clustering (0 = all cores; same result)")
      ->capture_default_str();

  std::string default_data, default_out;
  int default_threads = 0;
  auto* d = app.add_subcommand("train-default", "train the build's default vocabulary (docs/place-recognition.md)");
  d->add_option("--shared-data", default_data,
                "ablation: also train on the real excerpts in this folder (kitti07_first160, ntsd150_euroc); "
                "not the build's default");
  d->add_option("--out", default_out, "output vocabulary file")->required();
  d->add_option("--threads", default_threads, "threads rendering, extracting ORB and clustering (0 = all cores; same result)")
      ->capture_default_str();

  std::string info_path;
  auto* i = app.add_subcommand("info", "print a vocabulary's parameters and load time");
  i->add_option("file", info_path, "vocabulary file")->required();

  std::string query_vocab;
  std::vector<std::string> query_images;
  int query_features = 1000;
  auto* q = app.add_subcommand("query", "bag-of-words scores between images (debugging)");
  q->add_option("--vocab", query_vocab, "vocabulary file")->required();
  q->add_option("--images", query_images, "images to compare")->required();
  q->add_option("--features", query_features, "ORB features per image")->capture_default_str();

  std::string convert_in, convert_out;
  auto* c = app.add_subcommand("convert", "import a DBoW2 text vocabulary (ORB-SLAM's ORBvoc.txt)");
  c->add_option("--dbow2-text", convert_in, "DBoW2 text vocabulary")->required();
  c->add_option("--out", convert_out, "output vocabulary file")->required();

  CLI11_PARSE(app, argc, argv);
  if (*t) return Train(train);
  if (*d) return TrainDefault(default_data, default_out, default_threads);
  if (*c) return Convert(convert_in, convert_out);
  if (*i) return Info(info_path);
  return Query(query_vocab, query_images, query_features);
}
