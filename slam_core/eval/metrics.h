// Trajectory error metrics with evo's conventions (evo_ape / evo_rpe, pose relation
// "translation_part" and "angle_deg"): statistics, absolute translation error and relative
// pose error on already associated (and aligned) pose sequences. See docs/evaluation.md.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "slam_core/geometry/se3.h"

namespace ccm {

/// Statistics of an error sample, as evo reports them: std is the population standard
/// deviation (numpy.std), median averages the two middle values for an even count.
struct ErrorStats {
  size_t count = 0;
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0;
};
ErrorStats ComputeStats(const std::vector<double>& values);
/// Nearest-rank percentile, q in [0, 1] (0.5: median, 0.95: p95); 0 for no values.
double Percentile(std::vector<double> values, double q);
/// Length of the path through the poses' positions [m].
double PathLengthM(const std::vector<SE3>& poses);

/// Scale drift of a monocular estimate. The associated pairs are cut into consecutive
/// windows of `window_m` metres of ground-truth path; a window's scale is the spread of its
/// ground-truth positions over the spread of its estimated ones (RMS distance to their
/// centroid: rotation-free, so straight stretches count too). A trajectory whose scale
/// drifts has windows whose scales differ although its ATE after one Sim(3) may look
/// moderate: the ATE mixes scale drift with rotation drift, this separates it.
struct ScaleWindow {
  size_t first = 0, last = 0;  ///< pair indices (inclusive)
  double gt_path_m = 0.0;
  double scale = 0.0;          ///< gt spread / est spread
};
struct ScaleDrift {
  std::vector<ScaleWindow> windows;
  double min_scale = 0.0, max_scale = 0.0;  ///< over the windows (0 without any)
  /// Largest over smallest window scale (1: no drift); 0 with fewer than two windows.
  double max_over_min = 0.0;
};
ScaleDrift ComputeScaleDrift(const std::vector<SE3>& gt, const std::vector<SE3>& est, double window_m);

/// ATE translation part: ||t_est_i - t_gt_i|| for associated (aligned) poses [m].
std::vector<double> AbsoluteTranslationErrors(const std::vector<SE3>& gt,
                                              const std::vector<SE3>& est);

/// Rotation angle of a rotation [deg], in [0, 180].
double RotationAngleDeg(const Eigen::Quaterniond& q);

enum class RpeDeltaUnit { kFrames, kMeters };

struct RpeOptions {
  double delta = 1.0;                        ///< frames (integer >= 1) or metres (> 0) of gt path
  RpeDeltaUnit unit = RpeDeltaUnit::kFrames;
  bool all_pairs = false;  ///< false: consecutive non-overlapping pairs (evo default)
  bool Validate(std::string* error) const;
};

struct RpeResult {
  std::vector<std::pair<size_t, size_t>> pairs;  ///< (i, j) indices into the sequences
  std::vector<double> translation_errors_m;
  std::vector<double> rotation_errors_deg;
  ErrorStats translation_m;
  ErrorStats rotation_deg;
};

/// Index pairs (i, j) chosen like evo.core.filters: by frame count, or by path length
/// travelled on the ground truth.
std::vector<std::pair<size_t, size_t>> RpePairs(const std::vector<SE3>& gt, const RpeOptions& options);

/// E = (gt_i^-1 gt_j)^-1 (est_i^-1 est_j); translation error ||t(E)||, rotation error angle(E).
RpeResult ComputeRpe(const std::vector<SE3>& gt, const std::vector<SE3>& est,
                     const RpeOptions& options);

}  // namespace ccm
