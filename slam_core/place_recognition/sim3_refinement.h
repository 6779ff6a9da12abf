// Reprojection refinement of a candidate -> query Sim(3) (ORB-SLAM's OptimizeSim3): each
// 3D-3D match gives two residuals, the candidate point projected into the query image and
// the query point projected into the candidate image, in pixels over the keypoint's level
// sigma, Huber-robustified. Two rounds: optimise, drop matches above the chi2 threshold,
// optimise again. Works with any CameraModel (projection Jacobians by numeric
// differentiation on a 7-dof Sim(3) increment). Stateless; safe from any thread.
#pragma once

#include <string>
#include <vector>

#include "slam_core/geometry/sim3.h"
#include "slam_core/matching/match_types.h"
#include "slam_core/place_recognition/verification_view.h"

namespace ccm {

struct Sim3RefineOptions {
  int max_iterations = 5;       ///< Levenberg-Marquardt iterations per round
  double huber_px = 3.16;       ///< Huber threshold on the normalized error (sqrt(10), ORB-SLAM)
  double inlier_chi2 = 10.0;    ///< squared normalized error per image to stay an inlier
  int rounds = 2;               ///< optimise / drop outliers repetitions
  std::string Validate() const;
};

struct Sim3RefineResult {
  bool ok = false;                  ///< false if too few usable matches or the solver failed
  Sim3 query_from_candidate;
  std::vector<bool> inliers;        ///< per input match (false also for matches without 3D)
  int num_inliers = 0;
};

/// Refines `initial` (p_query = S * p_candidate) on the matches (index1 = candidate keypoint,
/// index2 = query keypoint) whose keypoints both have 3D points.
Sim3RefineResult RefineSim3(const VerificationView& candidate, const VerificationView& query,
                            const std::vector<FeatureMatch>& matches, const Sim3& initial,
                            const Sim3RefineOptions& options = {});

}  // namespace ccm
