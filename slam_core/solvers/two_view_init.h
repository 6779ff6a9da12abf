// Monocular two-view initialization: fits an essential matrix (5-point RANSAC) and a
// homography (4-point RANSAC) to the same bearing correspondences, picks one with the
// ORB-SLAM score ratio R_H = S_H / (S_H + S_E), recovers the motion (homography:
// the decomposition with the most points passing cheirality, parallax and error checks)
// and triangulates the inliers. Translation has unit norm; points are in the cam1 frame.
// Usage: TwoViewInitOptions o; o.focal_px = fx; auto r = InitializeTwoView(b1, b2, o);
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/geometry/se3.h"
#include "slam_core/solvers/relative_pose.h"
#include "slam_core/solvers/solver_common.h"

namespace ccm::solvers {

enum class TwoViewModel { kNone, kEssential, kHomography };

struct TwoViewInitOptions {
  /// Focal length in pixels of the camera(s): converts pixel noise to angles. Required.
  double focal_px = 0.0;
  /// Keypoint noise (1 sigma, pixels). Thresholds are chi-square bounds in sigma units:
  /// homography transfer and triangulation error sqrt(5.991) sigma, epipolar sqrt(3.841) sigma.
  double sigma_px = 1.0;
  int max_iterations = 200;
  double confidence = 0.999;
  std::uint64_t seed = 42;
  RelativePoseAlgorithm essential_algorithm = RelativePoseAlgorithm::kStewenius5pt;
  /// The homography is chosen when R_H exceeds this (ORB-SLAM 2's value). Measured over
  /// 30 seeds, 30 % outliers: planes 0.44-0.57 at noise = sigma, 0.58-0.67 at noise =
  /// sigma / 2; general 3D scenes 0.07-0.18.
  double min_homography_ratio = 0.40;
  /// Median parallax of the triangulated points must reach this (degrees).
  double min_parallax_deg = 1.0;
  /// Points counted as triangulated need cos(parallax) below this (0.99998 ~ 0.36 deg).
  double point_max_cos_parallax = 0.99998;
  int min_triangulated = 50;
  /// The motion must explain at least this fraction of the chosen model's inliers by
  /// triangulated points...
  double min_triangulated_fraction = 0.9;
  /// ...or, when set, by triangulated plus distant points (too little parallax to
  /// triangulate: their rays agree after the motion's rotation), as ORB-SLAM counts them.
  /// Driving forward most matches are distant and only counting them initializes; where
  /// all points are near (halls, rooms) counting them accepts smaller baselines, whose
  /// initial maps were worse (docs/vo.md, "Initialization on the road").
  bool count_distant_points = false;
  /// Homography: the second-best motion must have < this fraction of the best's points.
  double max_second_best_ratio = 0.75;
  /// The median angle left after the best pure rotation (the flow no rotation explains)
  /// must reach this. A short baseline leaves the motion ambiguous: on generated halls
  /// both the essential matrix and the homography returned motions 73-99 deg off in
  /// translation direction from frames 0.1-0.5 s apart whose triangulated parallax passed
  /// min_parallax_deg, and the VO kept the distorted map. 0: off.
  double min_rotation_residual_deg = 0.0;
  /// The chosen motion must beat every motion whose translation direction is at least
  /// 30 deg away by this robust cost (Cauchy at 2 sigma, sigma^2 units; see
  /// ProfileTranslationDirections). Checks the essential matrix's motion only (the
  /// homography's decompositions have their own test). On a pure plane every view has such
  /// a rival (the plane's other decomposition), so a caller that keeps trying must give up
  /// refusing at some point (the VO: init_max_ambiguous_attempts). 0: off.
  double min_motion_cost_gap = 0.0;

  std::string Validate() const;
};

struct TwoViewInitResult {
  SolverStatus status = SolverStatus::kInvalidInput;
  std::string message;
  TwoViewModel model = TwoViewModel::kNone;
  /// S_H / (S_H + S_E); 0 when neither model scored.
  double homography_ratio = 0.0;
  /// Maps cam1 points into cam2; |translation| = 1.
  SE3 cam2_from_cam1;
  /// One entry per correspondence; set where the point passed all checks.
  std::vector<std::optional<Eigen::Vector3d>> points_cam1;
  int num_inliers = 0;        // of the chosen model
  int num_triangulated = 0;
  int num_distant = 0;        // inliers with too little parallax under the chosen motion
  double median_parallax_deg = 0.0;
  /// Median angle left after the best pure rotation (set when min_rotation_residual_deg > 0).
  double rotation_residual_deg = 0.0;
  /// Robust cost by which the chosen motion beats its best rival >= 30 deg away in
  /// translation direction, and that rival's angle (set when min_motion_cost_gap > 0).
  double motion_cost_gap = 0.0;
  double rival_angle_deg = 0.0;

  bool ok() const { return status == SolverStatus::kOk; }
};

TwoViewInitResult InitializeTwoView(const std::vector<Eigen::Vector3d>& bearings1,
                                    const std::vector<Eigen::Vector3d>& bearings2,
                                    const TwoViewInitOptions& options);

/// ORB-SLAM-style model scores over all correspondences: each residual (both directions)
/// inside its chi-square gate adds gate - chi2, with chi2 = (error / sigma)^2. Gates:
/// 5.991 for homography transfer errors, 3.841 for epipolar distances (ORB-SLAM uses
/// 5.991 for both margins, which biases against the homography). Exposed for diagnostics.
double ScoreHomographyModel(const Eigen::Matrix3d& cam2_H_cam1, const std::vector<Eigen::Vector3d>& bearings1,
                            const std::vector<Eigen::Vector3d>& bearings2, double focal_px, double sigma_px);
double ScoreEssentialModel(const SE3& cam2_from_cam1, const std::vector<Eigen::Vector3d>& bearings1,
                           const std::vector<Eigen::Vector3d>& bearings2, double focal_px, double sigma_px);

}  // namespace ccm::solvers
