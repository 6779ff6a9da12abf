// Global bundle adjustment of one server map without stopping registration: the map is
// copied into a BundleProblem under the shared structure lock, optimized with no lock held
// (abortable, so a loop closure or fusion does not wait for it), and written back under the
// exclusive lock as corrections: each keyframe in the snapshot takes T_new = T_ba *
// T_snapshot^-1 * T_now, so changes made meanwhile survive; keyframes and points added
// meanwhile follow their spanning-tree ancestor / reference keyframe. A result whose map was
// corrected or fused meanwhile (generation changed) is dropped and the caller runs it again.
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "slam_core/server/server_map.h"

namespace ccm {

struct GlobalBaOptions {
  int iterations = 10;
  int threads = 2;
  /// Points need this many observations to enter (fewer constrain nothing).
  int min_observations = 2;
  /// Observations whose squared whitened error exceeds this before the BA are left out
  /// (gross outliers: ~40 px at level 0).
  double gross_outlier_chi2 = 1600.0;
};

struct GlobalBaReport {
  enum class Outcome { kApplied, kAborted, kStale, kFailed, kEmpty } outcome = Outcome::kEmpty;
  MapId map;
  int keyframes = 0, points = 0, observations = 0;
  int keyframes_added_meanwhile = 0;
  int observations_dropped = 0;  ///< gross outliers left out
  int iterations = 0;
  double initial_rmse_px = 0.0, final_rmse_px = 0.0;
  double snapshot_s = 0.0, solve_s = 0.0, write_back_s = 0.0;
  std::string message;
};
const char* GlobalBaOutcomeName(GlobalBaReport::Outcome outcome);

GlobalBaReport RunGlobalBundleAdjustment(const std::shared_ptr<ServerMap>& map, const GlobalBaOptions& options,
                                         const std::atomic<bool>* abort);

}  // namespace ccm
