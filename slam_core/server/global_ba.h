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
#include <unordered_set>
#include <vector>

#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/server/server_map.h"

namespace ccm {

struct GlobalBaOptions {
  int iterations = 10;
  int threads = 2;
  /// Points need this many observations to enter (fewer constrain nothing).
  int min_observations = 2;
  /// Points whose rays from their keyframes span less than this angle (0: none) are held fixed
  /// and afterwards follow their reference keyframe, like points added meanwhile. Free, their
  /// depth is nearly unconstrained, so a Gauss-Newton step slides one along its ray until it
  /// crosses a camera and the whole step is thrown away (half of the iterations of a 400- or
  /// 1,000-keyframe BA of the hall3 copies); held, they still pin the rotations. Off by
  /// default: 1 deg helped both real two-agent splits but made fused maps of generated scenes
  /// worse (docs/server.md, "Points of low parallax in the global BA").
  double min_parallax_deg = 0.0;
  /// Instead of holding them, optimize those points in inverse-depth coordinates of their
  /// reference keyframe (or the first keyframe here that sees them): still free, but a far point
  /// may go to infinity instead of through a camera, and no step is thrown away for it.
  bool low_parallax_inverse_depth = false;
  /// Observations whose squared whitened error exceeds this before the BA are left out
  /// (gross outliers: ~40 px at level 0).
  double gross_outlier_chi2 = 1600.0;
  opt::BaLinearSolver linear_solver = opt::BaLinearSolver::kAuto;
  /// A map with more keyframes than this (0: no limit) is optimized only around
  /// `region_seeds` (the keyframes of the loop or fusion that asked for the BA): the nearest
  /// max_free_keyframes by covisibility, breadth first, are free; the keyframes that see
  /// their points hold them in place, the rest of the map is not touched. The cost of a full
  /// BA grows with the cube of the keyframes where most of them see each other (bench_server:
  /// 7 s per iteration at 2,000 keyframes); the region's stays bounded. Without seeds the
  /// whole map is optimized (the final BA of a run, a BA asked for by hand).
  int max_free_keyframes = 0;
  std::vector<KeyframeId> region_seeds;
};

/// The solver settings RunGlobalBundleAdjustment uses (a robust pass, outlier rejection, a
/// plain pass of `iterations` each); bench_server times the same.
opt::BundleAdjusterOptions GlobalBaSolverOptions(const GlobalBaOptions& options, const std::atomic<bool>* abort);
/// True if the rays from two of the camera centres to the point meet at min_deg or more
/// (always true for min_deg <= 0).
bool HasParallax(const Eigen::Vector3d& point_w, const std::vector<Eigen::Vector3d>& centres_w, double min_deg);
/// The block of map point `mp` in a global BA that sees it through `obs` (pose indices into
/// `keyframes`, problem pose k = keyframes[k]): free, or with less than options.min_parallax_deg
/// of parallax held (*low_parallax set) or, with options.low_parallax_inverse_depth, anchored
/// as an inverse depth in its reference keyframe (the first one in `obs` if that is not among
/// them). The server's BA and bench_server build their points with it.
opt::PointBlock GlobalBaPointBlock(const MapPoint& mp, const std::vector<opt::Observation>& obs,
                                   const std::vector<std::shared_ptr<KeyFrame>>& keyframes,
                                   const GlobalBaOptions& options, bool* low_parallax);
/// Leaves out the observations whose chi2 before the BA exceeds options.gross_outlier_chi2 (or
/// that do not project); returns their indices in the problem as it was.
std::vector<size_t> DropGrossOutliers(opt::BundleProblem* problem, const GlobalBaOptions& options);
/// The keyframes a regional BA frees: `seeds` (those in the map), then their covisible
/// keyframes, hop by hop, strongest links first, until `max_free` are taken.
std::unordered_set<KeyframeId> CovisibleRegion(const Map& map, const std::vector<KeyframeId>& seeds, size_t max_free);

struct GlobalBaReport {
  enum class Outcome { kApplied, kAborted, kStale, kFailed, kEmpty } outcome = Outcome::kEmpty;
  MapId map;
  int keyframes = 0, points = 0, observations = 0;
  int free_keyframes = 0;  ///< of `keyframes`, those optimized (all but the fixed periphery of a region)
  int keyframes_added_meanwhile = 0;
  int observations_dropped = 0;  ///< gross outliers left out
  int points_low_parallax = 0;   ///< of `points`, those held or anchored for their parallax (GlobalBaOptions::min_parallax_deg)
  int iterations = 0;
  int rejected_steps = 0;  ///< of `iterations`, steps the solver threw away
  double initial_rmse_px = 0.0, final_rmse_px = 0.0;  ///< over every observation the BA saw
  double final_inlier_rmse_px = 0.0;  ///< over the observations it kept (the outliers it rejected grow)
  int final_inliers = 0;
  double snapshot_s = 0.0, solve_s = 0.0, write_back_s = 0.0;
  std::string message;
};
const char* GlobalBaOutcomeName(GlobalBaReport::Outcome outcome);

GlobalBaReport RunGlobalBundleAdjustment(const std::shared_ptr<ServerMap>& map, const GlobalBaOptions& options,
                                         const std::atomic<bool>* abort);

}  // namespace ccm
