// Why two overlapping agents never fused: bench_fusion --recall. Every map-matching query of
// one agent (PlaceMatchingOptions::fusion_trace) is compared with the simulator's ground
// truth: did a keyframe of the other agent in the database see the same place, was such a
// keyframe picked for verification, and if not, which retrieval test dropped it (the
// query's score bar, the common-word ratio, the group cut); if it was, where its
// verification stopped. This told retrieval from verification misses on unseen scenes.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "slam_core/server/place_matcher.h"
#include "tests/bench/fusion_scoring.h"

namespace ccm::bench {

struct MissedPairDiagnosis {
  int a = 0, b = 0;          ///< the pair (agent indices)
  int querying = 0;          ///< whose queries (a or b)
  int queries = 0;           ///< map-matching queries by `querying`
  int with_true_view = 0;    ///< ... where a keyframe of the other agent saw the same place
  int retrieved = 0;         ///< ... where such a keyframe was picked for verification
  /// Why the best true keyframe was not picked: below the query's score bar, too few common
  /// words, or its group cut (or out-ranked by the max_results best groups).
  int below_score = 0, below_common_words = 0, cut_by_groups = 0;
  std::map<std::string, int> stopped_at;  ///< verification stage of each retrieved true candidate
  std::vector<int> bow_matches;           ///< BoW matches of each retrieved true candidate
};

/// `stamps`: every keyframe's stamp (from the agents' batches); `agent_ids`: the run's agent
/// ids by index; `min_common_ratio`: the map-matching common-word ratio of the run.
std::vector<MissedPairDiagnosis> DiagnoseMissedPairs(const sim::Simulation& sim, const sim::OverlapTruth& truth,
                                                     const SceneScore& score,
                                                     const std::vector<FusionQueryTrace>& traces,
                                                     const std::map<KeyframeId, int64_t>& stamps,
                                                     const std::vector<AgentId>& agent_ids, double min_common_ratio);

std::string FormatDiagnosis(const MissedPairDiagnosis& d);

}  // namespace ccm::bench
