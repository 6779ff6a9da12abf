// bench_fusion's output: a block per scene as it finishes, a JSON line per scene (for
// scripts), and the final markdown report: a table per scene, a table per agent, recall by
// overlap kind, and the totals next to issue 27's goals.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/bench/fusion_recall.h"
#include "tests/bench/fusion_scoring.h"
#include "tests/sim/scene_generator.h"

namespace ccm::bench {

struct SceneResult {
  sim::GeneratedScene scene;
  SceneScore score;
  int64_t frames = 0;
  double wall_s = 0.0;
  double place_recognition_ms = 0.0;  ///< mean per query (database + verification)
  /// Global BAs applied: how many, their seconds in total, the longest and its keyframes.
  int global_bas = 0;
  double global_ba_total_s = 0.0, global_ba_max_s = 0.0;
  int global_ba_max_keyframes = 0;
  std::vector<std::string> global_ba_details;  ///< the server's line per global BA applied (--events)
  PlaceMatcherStats place;            ///< the place-recognition funnel (where candidates stopped)
  std::vector<MissedPairDiagnosis> missed;  ///< --recall: pairs that never fused, diagnosed
  std::string error;                  ///< the scene could not be replayed
};

/// `events`: also one line per fusion and loop (its ground-truth check and the server's detail).
std::string SceneBlock(const SceneResult& r, bool events = false);
nlohmann::json SceneJson(const SceneResult& r);
std::string Report(const std::vector<SceneResult>& results);

}  // namespace ccm::bench
