// 3D-3D similarity Sim(3) between two point sets: closed-form Umeyama (rotation,
// translation and scale; optionally fixed scale) and a seeded RANSAC around it. Used for
// loop closure and map fusion where two monocular maps differ by an unknown scale.
// Points should be expressed in camera frames (e.g. a_i in the loop keyframe, b_i in the
// current keyframe) so that the angular inlier test means "reprojects into both views".
// Usage: options.ransac.focal_px = fx; auto r = EstimateSim3(points_a, points_b, options);
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/geometry/sim3.h"
#include "slam_core/solvers/solver_common.h"

namespace ccm::solvers {

/// Least-squares b_from_a with b_i ~ s R a_i + t (Umeyama 1991). `indices` selects a
/// subset (all points if empty). nullopt when degenerate (< 3 points, collinear, zero spread).
std::optional<Sim3> AlignUmeyama(const std::vector<Eigen::Vector3d>& points_a,
                                 const std::vector<Eigen::Vector3d>& points_b,
                                 bool fix_scale = false, const std::vector<int>& indices = {});

enum class Sim3InlierMetric {
  /// Both directions: angle between b_i and S a_i seen from b's origin, and between a_i
  /// and S^-1 b_i seen from a's origin, each below ransac.threshold_px at focal_px
  /// (ORB-SLAM's Sim3Solver reprojection check without a camera model).
  kAngular,
  /// |b_i - S a_i| <= max_relative_distance * |b_i| (and symmetric in frame a).
  kRelativeDistance,
};

struct Sim3Options {
  Sim3InlierMetric metric = Sim3InlierMetric::kAngular;
  /// Used by kAngular (threshold_px, focal_px) and for iterations/confidence/seed always.
  RansacOptions ransac;
  /// Used by kRelativeDistance: allowed distance as a fraction of the point's depth.
  double max_relative_distance = 0.05;
  /// Fix scale to 1 (stereo/RGB-D or already scale-consistent maps).
  bool fix_scale = false;
  /// Re-estimate on all inliers and re-select, a few rounds.
  bool refine = true;
  int min_inliers = 6;

  std::string Validate() const;
};

struct Sim3Result {
  SolverStatus status = SolverStatus::kInvalidInput;
  std::string message;
  Sim3 b_from_a;
  std::vector<bool> inliers;
  int num_inliers = 0;
  int iterations = 0;

  bool ok() const { return status == SolverStatus::kOk; }
};

Sim3Result EstimateSim3(const std::vector<Eigen::Vector3d>& points_a,
                        const std::vector<Eigen::Vector3d>& points_b, const Sim3Options& options);

}  // namespace ccm::solvers
