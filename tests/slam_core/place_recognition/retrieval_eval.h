// Retrieval recall against ground truth, shared by place_recognition_test and
// bench_place_recognition: every keyframe queries a database of all keyframes (its own
// agent's within min_gap_s excluded); a query with a true revisit (same scene, SamePlace within
// revisit_dist_m / max_angle_deg) counts as a hit if one of the top-k candidates is within
// hit_dist_m / max_angle_deg. Several scenes in one database act as distractors for each
// other, as the maps of many teams would on one server. Keyframes come from the simulator
// (MakeScenarioKeyframes) or from a real sequence with ground truth (MakeDatasetKeyframes, no
// map points, so no verification).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/io/frame_source.h"
#include "tests/slam_core/place_recognition/sim_keyframes.h"

namespace ccm::test {

struct RetrievalOptions {
  double revisit_dist_m = 0.5;   ///< a query has a revisit if a candidate is this close ...
  double hit_dist_m = 1.0;       ///< ... and a returned candidate this close is a hit
  double max_angle_deg = 30.0;   ///< between optical axes, for both
  double min_gap_s = 10.0;       ///< own-agent keyframes closer in time are excluded
  int top_k = 3;
  bool verify = false;           ///< also run VerifyPlace on each top-k candidate
  std::optional<int> query_scene;  ///< only keyframes of this scene query (nullopt: all)
};

struct RetrievalStats {
  int keyframes = 0;
  int queries = 0;                  ///< queries with a revisit
  int hits_top1 = 0, hits_topk = 0;
  int verified_correct = 0, verified_wrong = 0;  ///< accepted with right / wrong Sim(3)
  int queries_verified = 0;         ///< revisit queries with >= 1 correctly verified candidate
  std::vector<double> query_ms;     ///< database query time of every keyframe

  double RecallTop1() const { return queries ? static_cast<double>(hits_top1) / queries : 0.0; }
  double RecallTopK() const { return queries ? static_cast<double>(hits_topk) / queries : 0.0; }
  void Add(const RetrievalStats& other);
};

/// Scores retrieval on `kfs` (their bow vectors; views only when options.verify).
RetrievalStats ScoreRetrieval(const std::vector<SimKeyframe>& kfs, std::size_t num_words,
                              const RetrievalOptions& options);

/// Recomputes bow and direct index of every keyframe with another vocabulary
/// (levels_up < 0: vocab.levels() - 2, ORB-SLAM's depth 2).
void TransformKeyframes(const Vocabulary& vocab, int levels_up, std::vector<SimKeyframe>* kfs);

/// Every frame of `source` that has ground truth, as a keyframe of agent 0 of `scene` (features,
/// bow and direct index; no map points). Empty string or the source's error.
std::string MakeDatasetKeyframes(FrameSource* source, const Vocabulary& vocab, int num_features, int scene,
                                 std::vector<SimKeyframe>* kfs);

/// Keyframes of every agent of a scenario (built-in, gen:SEED or YAML), one every
/// `spacing_s` seconds, map scales 1.0 / 0.6 / 1.7 by agent. Empty string or the error.
std::string MakeScenarioKeyframes(const std::string& scenario, const Vocabulary& vocab, double spacing_s,
                                  int scene, std::vector<SimKeyframe>* kfs);

}  // namespace ccm::test
