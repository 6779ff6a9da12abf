// Benchmark (not a test): vocabulary load time (simulator vocabulary and a synthetic
// ORB-SLAM-size k=10 L=6 tree), BoW transform time, keyframe database insert and query time
// with 5,000 keyframes, verification time, and precision/recall on a simulator scenario.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <random>

#include "slam_core/place_recognition/keyframe_database.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "slam_core/io/dataset.h"
#include "tests/slam_core/place_recognition/retrieval_eval.h"
#include "tests/slam_core/place_recognition/sim_keyframes.h"

namespace ccm::test {
namespace {

using Clock = std::chrono::steady_clock;
double Ms(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// A full k^L tree with random descriptors: measures file size and load speed of a
// vocabulary as large as ORB-SLAM's, without training one.
Vocabulary SyntheticVocabulary(int k, int levels) {
  std::mt19937_64 rng(1);
  std::vector<Vocabulary::Node> nodes(1);
  std::vector<NodeId> frontier{0};
  for (int l = 0; l < levels; ++l) {
    std::vector<NodeId> next;
    for (NodeId p : frontier) {
      for (int c = 0; c < k; ++c) {
        Vocabulary::Node n;
        for (auto& b : n.descriptor) b = static_cast<uint8_t>(rng());
        n.parent = p;
        n.weight = 1.f + static_cast<float>(rng() % 1000) / 250.f;
        next.push_back(static_cast<NodeId>(nodes.size()));
        nodes.push_back(n);
      }
    }
    frontier = std::move(next);
  }
  Vocabulary v;
  v.Assign(k, levels, std::move(nodes));
  return v;
}

void BenchLoad(const std::string& path, const char* label) {
  std::string error;
  double best = 1e9;
  std::size_t words = 0;
  for (int i = 0; i < 3; ++i) {
    const auto t0 = Clock::now();
    auto v = LoadVocabularyFile(path, &error);
    best = std::min(best, Ms(t0));
    if (!v) {
      std::printf("load %s failed: %s\n", path.c_str(), error.c_str());
      return;
    }
    words = v->num_words();
  }
  std::printf("vocabulary load (%s, %zu words): %.1f ms (best of 3)\n", label, words, best);
}

// 5,000 database bags of words made from real keyframes: each copy keeps ~70% of its words and
// replaces the rest by words of other real keyframes, so list lengths follow real statistics.
std::vector<BowVector> SynthesizeBows(const std::vector<SimKeyframe>& real, int n) {
  std::mt19937_64 rng(5);
  std::vector<BowVector> out;
  for (int i = 0; i < n; ++i) {
    const BowVector& base = real[i % real.size()].bow;
    const BowVector& donor = real[rng() % real.size()].bow;
    std::map<WordId, float> words;
    for (const auto& e : base.entries) {
      if (rng() % 10 < 7) words[e.first] += e.second;
    }
    for (const auto& e : donor.entries) {
      if (rng() % 10 < 3) words[e.first] += e.second;
    }
    BowVector b;
    b.entries.assign(words.begin(), words.end());
    b.NormalizeL1();
    out.push_back(std::move(b));
  }
  return out;
}

void BenchDatabase(const std::vector<SimKeyframe>& kfs, std::size_t num_words, int num_keyframes) {
  const std::vector<BowVector> bows = SynthesizeBows(kfs, num_keyframes);
  KeyframeDatabase db(num_words);
  auto t0 = Clock::now();
  for (int i = 0; i < num_keyframes; ++i) {
    db.Add(KeyframeId::Make(static_cast<AgentId>(1 + i % 3), i + 1), MapId::Make(1 + i % 3, 1), bows[i]);
  }
  const double insert_ms = Ms(t0) / num_keyframes;
  std::vector<double> times;
  QueryFilter other_maps;
  other_maps.exclude_maps = {MapId::Make(1, 1)};
  double sum_candidates = 0;
  for (std::size_t q = 0; q < kfs.size(); ++q) {
    t0 = Clock::now();
    const auto r = db.Query(kfs[q].bow, q % 2 ? other_maps : QueryFilter{}, 10);
    times.push_back(Ms(t0));
    sum_candidates += r.size();
  }
  std::sort(times.begin(), times.end());
  std::vector<double> grouped;
  CandidateOptions options;
  for (std::size_t q = 0; q < kfs.size(); ++q) {
    t0 = Clock::now();
    db.DetectCandidates(kfs[q].bow, {}, options);
    grouped.push_back(Ms(t0));
  }
  std::sort(grouped.begin(), grouped.end());
  std::printf("database with %d keyframes (avg %zu words each): insert %.3f ms/keyframe\n",
              num_keyframes, bows[0].size(), insert_ms);
  std::printf("  Query top-10:        median %.2f ms, p95 %.2f ms, max %.2f ms (%zu queries)\n",
              times[times.size() / 2], times[times.size() * 95 / 100], times.back(), times.size());
  std::printf("  DetectCandidates:    median %.2f ms, p95 %.2f ms\n", grouped[grouped.size() / 2],
              grouped[grouped.size() * 95 / 100]);
  t0 = Clock::now();
  for (int i = 0; i < num_keyframes; i += 10) db.Erase(KeyframeId::Make(static_cast<AgentId>(1 + i % 3), i + 1));
  std::printf("  erase:               %.3f ms/keyframe\n", Ms(t0) / (num_keyframes / 10));
}

// Top-1 precision/recall over score thresholds, and after geometric verification.
void BenchPrecisionRecall(const std::vector<SimKeyframe>& kfs, const std::string& scenario,
                          std::size_t num_words) {
  KeyframeDatabase db(num_words);
  for (const auto& kf : kfs) db.Add(KeyframeId::Make(kf.agent + 1, kf.index + 1), MapId::Make(kf.agent + 1, 1), kf.bow);
  struct Row { double score; bool correct; bool has_revisit; bool verified_ok; bool verified_bad; };
  std::vector<Row> rows;
  std::vector<double> verify_ms, verify_opt_ms, err_plain, err_opt;
  for (const auto& q : kfs) {
    QueryFilter f;
    bool has_revisit = false;
    for (const auto& c : kfs) {
      const bool near_in_time = c.agent == q.agent && std::abs(c.time_s - q.time_s) < 10.0;
      if (near_in_time) f.exclude_keyframes.push_back(KeyframeId::Make(c.agent + 1, c.index + 1));
      else has_revisit |= SamePlace(q.world_from_cam, c.world_from_cam, 0.5, 30.0);
    }
    const auto r = db.Query(q.bow, f, 1);
    if (r.empty()) continue;
    const auto& c = *std::find_if(kfs.begin(), kfs.end(), [&](const SimKeyframe& k) {
      return KeyframeId::Make(k.agent + 1, k.index + 1) == r[0].keyframe;
    });
    auto t0 = Clock::now();
    const VerificationResult v = VerifyPlace(c.view, q.view);
    verify_ms.push_back(Ms(t0));
    double dt = 0, dr = 0;
    Sim3Error(v.query_from_candidate, TrueQueryFromCandidate(c, q), q.map_scale, &dt, &dr);
    VerificationOptions with_opt;
    with_opt.optimize = true;
    t0 = Clock::now();
    const VerificationResult vo = VerifyPlace(c.view, q.view, with_opt);
    verify_opt_ms.push_back(Ms(t0));
    if (v.accepted && vo.accepted) {
      double dto = 0, dro = 0;
      Sim3Error(vo.query_from_candidate, TrueQueryFromCandidate(c, q), q.map_scale, &dto, &dro);
      err_plain.push_back(dt);
      err_opt.push_back(dto);
    }
    const bool pose_ok = dt < 0.3 && dr < 5.0;
    rows.push_back({r[0].score, SamePlace(q.world_from_cam, c.world_from_cam, 1.0, 30.0), has_revisit,
                    v.accepted && pose_ok, v.accepted && !pose_ok});
  }
  int revisits = 0;
  for (const auto& r : rows) revisits += r.has_revisit;
  std::printf("precision/recall on %s (%zu keyframes, %d with a revisit), top-1 candidate:\n",
              scenario.c_str(), kfs.size(), revisits);
  for (double th : {0.0, 0.02, 0.04, 0.06, 0.08, 0.10}) {
    int tp = 0, fp = 0, tp_revisit = 0;
    for (const auto& r : rows) {
      if (r.score < th) continue;
      r.correct ? ++tp : ++fp;
      tp_revisit += r.correct && r.has_revisit;
    }
    std::printf("  score >= %.2f: precision %.3f, recall %.3f\n", th, tp + fp ? double(tp) / (tp + fp) : 1.0,
                revisits ? double(tp_revisit) / revisits : 0.0);
  }
  int ok = 0, bad = 0, ok_revisit = 0;
  for (const auto& r : rows) {
    ok += r.verified_ok;
    bad += r.verified_bad;
    ok_revisit += r.verified_ok && r.has_revisit;
  }
  std::sort(verify_ms.begin(), verify_ms.end());
  std::printf("  after verification: %d accepted correct, %d accepted wrong (precision %.3f), "
              "recall %.3f; verification median %.2f ms\n", ok, bad, ok + bad ? double(ok) / (ok + bad) : 1.0,
              revisits ? double(ok_revisit) / revisits : 0.0, verify_ms[verify_ms.size() / 2]);
  std::sort(verify_opt_ms.begin(), verify_opt_ms.end());
  std::sort(err_plain.begin(), err_plain.end());
  std::sort(err_opt.begin(), err_opt.end());
  if (!err_plain.empty()) {
    std::printf("  Sim(3) translation error of accepted pairs (%zu): RANSAC-refined median %.3f m p90 %.3f m; "
                "with reprojection optimisation median %.3f m p90 %.3f m (verification median %.2f ms)\n",
                err_plain.size(), err_plain[err_plain.size() / 2], err_plain[err_plain.size() * 9 / 10],
                err_opt[err_opt.size() / 2], err_opt[err_opt.size() * 9 / 10], verify_opt_ms[verify_opt_ms.size() / 2]);
  }
}

struct NamedVocabulary {
  std::string path;
  Vocabulary vocab;
};

void PrintStats(const char* label, const std::string& vocab, const RetrievalStats& st, bool verified) {
  std::vector<double> ms = st.query_ms;
  std::sort(ms.begin(), ms.end());
  std::printf("  %-14s %-44s %5d kf %5d queries  top-1 %.3f  top-3 %.3f", label, vocab.c_str(), st.keyframes,
              st.queries, st.RecallTop1(), st.RecallTopK());
  if (verified) {
    std::printf("  verified %.3f (%d right, %d wrong)", st.queries ? double(st.queries_verified) / st.queries : 0.0,
                st.verified_correct, st.verified_wrong);
  }
  std::printf("  query median %.2f ms\n", ms.empty() ? 0.0 : ms[ms.size() / 2]);
}

// Held-out generated scenes, all in one database (each scene a distractor for the others):
// rendered once, transformed with every vocabulary.
std::vector<SimKeyframe> BenchHeldOut(const std::vector<NamedVocabulary>& vocabs, std::uint64_t first,
                                      std::uint64_t last, double spacing_s, int levels_up) {
  std::vector<SimKeyframe> kfs;
  auto t0 = Clock::now();
  for (std::uint64_t seed = first; seed <= last; ++seed) {
    const std::string error =
        MakeScenarioKeyframes("gen:" + std::to_string(seed), vocabs[0].vocab, spacing_s, static_cast<int>(seed), &kfs);
    if (!error.empty()) std::fprintf(stderr, "%s\n", error.c_str());
  }
  std::printf("held-out generated scenes gen:%llu..%llu: %zu keyframes (one every %.2f s) rendered in %.0f s\n",
              static_cast<unsigned long long>(first), static_cast<unsigned long long>(last), kfs.size(), spacing_s,
              Ms(t0) / 1e3);
  RetrievalOptions options;
  options.verify = true;
  for (const auto& v : vocabs) {
    TransformKeyframes(v.vocab, levels_up, &kfs);
    RetrievalStats all;
    for (std::uint64_t seed = first; seed <= last; ++seed) {
      options.query_scene = static_cast<int>(seed);
      const RetrievalStats st = ScoreRetrieval(kfs, v.vocab.num_words(), options);
      all.Add(st);
      PrintStats(("gen:" + std::to_string(seed)).c_str(), v.path, st, true);
    }
    all.keyframes = static_cast<int>(kfs.size());
    PrintStats("all", v.path, all, true);
  }
  return kfs;
}

// The real excerpts: no revisits inside them, so every frame queries the frames at least
// min_gap_s away; a true match is within revisit_dist_m and 30 deg (ground truth). The other
// sequence and `distractors` (simulator keyframes) share the database.
struct RealSequence {
  const char* folder;
  const char* ground_truth;  ///< relative to the folder; "" = the reader's own
  double min_gap_s, dist_m;
};
// Gaps and distances where the nearest allowed frames are true matches for almost every
// query (KITTI: 159 of 160; NTSD: 144 of 150) but far enough to need some viewpoint
// invariance; at 2 s / 15 m on KITTI the views share too little for any vocabulary.
constexpr RealSequence kRealSequences[] = {
    {"kitti07_first160", "poses_07_first160_kitti.txt", 1.0, 10.0},  // 10 Hz, 0.1-0.85 m/frame
    {"ntsd150_euroc", "", 0.5, 1.0},                                   // 30 Hz, 3.8 m in 150 frames
};

void BenchReal(const std::vector<NamedVocabulary>& vocabs, const std::string& data_dir,
               std::vector<SimKeyframe> distractors) {
  std::vector<SimKeyframe> kfs = std::move(distractors);
  const std::size_t num_distractors = kfs.size();
  int scene = -1;
  for (const auto& seq : kRealSequences) {
    DatasetOptions o;
    o.path = data_dir + "/" + seq.folder;
    if (*seq.ground_truth) o.ground_truth_path = o.path + "/" + seq.ground_truth;
    IoStatus status;
    auto source = OpenDataset(o, &status);
    if (!source) {
      std::printf("real sequence %s: not available (%s)\n", seq.folder, status.message().c_str());
      continue;
    }
    const std::string error = MakeDatasetKeyframes(source.get(), vocabs[0].vocab, 1000, scene--, &kfs);
    if (!error.empty()) std::printf("real sequence %s: %s\n", seq.folder, error.c_str());
  }
  std::printf("real sequences: %zu frames, %zu simulator distractors in the database\n",
              kfs.size() - num_distractors, num_distractors);
  std::vector<SimKeyframe> alone(kfs.begin() + static_cast<std::ptrdiff_t>(num_distractors), kfs.end());
  for (const auto& v : vocabs) {
    TransformKeyframes(v.vocab, -1, &kfs);
    TransformKeyframes(v.vocab, -1, &alone);
    for (int s = 0; s < static_cast<int>(std::size(kRealSequences)); ++s) {
      RetrievalOptions options;
      options.query_scene = -1 - s;
      options.min_gap_s = kRealSequences[s].min_gap_s;
      options.revisit_dist_m = options.hit_dist_m = kRealSequences[s].dist_m;
      PrintStats(kRealSequences[s].folder, v.path, ScoreRetrieval(alone, v.vocab.num_words(), options), false);
      PrintStats("+distractors", v.path, ScoreRetrieval(kfs, v.vocab.num_words(), options), false);
    }
  }
}

}  // namespace
}  // namespace ccm::test

int main(int argc, char** argv) {
  using namespace ccm;
  using namespace ccm::test;
  CLI::App app{"bench_place_recognition: vocabulary, database and verification timings, precision/recall"};
  std::string scenario = "hall3";
  std::int64_t stride = 8;
  int num_keyframes = 5000, levels_up = -1;
  bool big_vocab = true, timings = true;
  std::vector<std::string> vocab_paths;
  std::string heldout, real_data;
  double spacing_s = 0.5;
  app.add_option("--scenario", scenario, "simulator scenario")->capture_default_str();
  app.add_option("--stride", stride, "keyframe every n-th frame")->capture_default_str();
  app.add_option("--keyframes", num_keyframes, "database size for timings")->capture_default_str();
  app.add_flag("!--no-big-vocab", big_vocab, "skip the synthetic k=10 L=6 load test");
  app.add_option("--vocab", vocab_paths, "vocabularies to measure (repeatable; default: the build's default)");
  app.add_option("--heldout", heldout, "recall on generated scenes FIRST-LAST (e.g. 7001-7010), never trained on");
  app.add_option("--spacing", spacing_s, "held-out keyframe spacing [s]")->capture_default_str();
  app.add_option("--levels-up", levels_up, "direct index levels up for verification (-1: depth 2)")
      ->capture_default_str();
  app.add_option("--real-data", real_data, "folder with kitti07_first160 / ntsd150_euroc: recall on real frames");
  app.add_flag("!--no-timings", timings, "skip the timing and hall3 precision part");
  CLI11_PARSE(app, argc, argv);

  if (vocab_paths.empty()) vocab_paths.push_back(CCM_DEFAULT_VOCAB_FILE);
  std::vector<NamedVocabulary> vocabs;
  for (const auto& p : vocab_paths) {
    std::string error;
    auto v = LoadVocabularyFile(p, &error);
    if (!v) {
      std::fprintf(stderr, "%s: %s\n", p.c_str(), error.c_str());
      return 1;
    }
    vocabs.push_back({std::filesystem::path(p).filename().string(), std::move(*v)});
  }
  std::vector<SimKeyframe> heldout_kfs;
  if (!heldout.empty()) {
    unsigned long long first = 0, last = 0;
    if (std::sscanf(heldout.c_str(), "%llu-%llu", &first, &last) != 2 || last < first) {
      std::fprintf(stderr, "--heldout FIRST-LAST\n");
      return 1;
    }
    heldout_kfs = BenchHeldOut(vocabs, first, last, spacing_s, levels_up);
  }
  if (!real_data.empty()) BenchReal(vocabs, real_data, std::move(heldout_kfs));
  if (!timings) return 0;
  BenchLoad(vocab_paths[0], vocabs[0].path.c_str());
  if (big_vocab) {
    const auto t0 = Clock::now();
    const Vocabulary big = SyntheticVocabulary(10, 6);
    const std::string path = "/tmp/bench_place_recognition_k10_l6.ccmvoc";
    const std::string error = SaveVocabularyFile(big, path);
    if (error.empty()) {
      std::printf("synthetic k=10 L=6 vocabulary: %zu words, built+saved in %.0f ms\n", big.num_words(), Ms(t0));
      BenchLoad(path, "synthetic k=10 L=6");
      std::remove(path.c_str());
    }
  }
  const Vocabulary& vocab = vocabs[0].vocab;
  std::string error;
  auto s = sim::LoadScenario(scenario, &error);
  if (!s) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  std::shared_ptr<const sim::Simulation> simulation = sim::Simulation::Create(*s, &error);
  std::vector<SimKeyframe> kfs;
  const std::vector<double> scales = {1.0, 0.6, 1.7};
  auto t0 = Clock::now();
  for (int a = 0; a < simulation->num_agents(); ++a) {
    SimKeyframeOptions o;
    o.stride = stride;
    o.map_scale = scales[a % scales.size()];
    for (auto& kf : MakeSimKeyframes(*simulation, a, vocab, o)) kfs.push_back(std::move(kf));
  }
  std::printf("%zu simulator keyframes rendered in %.1f s\n", kfs.size(), Ms(t0) / 1e3);
  t0 = Clock::now();
  BowVector bow;
  FeatureVector fv;
  for (const auto& kf : kfs) vocab.Transform(kf.view.features.descriptors, &bow, &fv, vocab.levels() - 2);
  std::printf("BoW transform (1000 ORB, k=%d L=%d, with direct index): %.3f ms/image\n", vocab.branching(),
              vocab.levels(), Ms(t0) / kfs.size());
  BenchDatabase(kfs, vocab.num_words(), num_keyframes);
  BenchPrecisionRecall(kfs, scenario, vocab.num_words());
  return 0;
}
