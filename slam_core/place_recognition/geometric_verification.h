// Geometric verification of a place candidate (loop or map overlap), CCM-SLAM/ORB-SLAM style:
// BoW-guided descriptor matches (features under the same vocabulary node) between keypoints
// that have 3D points -> Sim(3) RANSAC on the 3D-3D pairs (angular inlier test, so it works
// for any camera model) -> guided search by projection in both directions -> RANSAC again on
// the enlarged set (refinement) -> accept on match/inlier thresholds.
// Inputs are value snapshots (VerificationView), so agent maps, server maps and different
// cameras all work. Stateless function; safe from any thread.
#pragma once

#include <string>
#include <vector>

#include "slam_core/geometry/sim3.h"
#include "slam_core/matching/descriptor_matcher.h"
#include "slam_core/matching/projection_matcher.h"
#include "slam_core/place_recognition/sim3_refinement.h"
#include "slam_core/place_recognition/verification_view.h"
#include "slam_core/solvers/similarity.h"

namespace ccm {

struct VerificationOptions {
  DescriptorMatchOptions bow_match = [] {
    DescriptorMatchOptions o;
    o.max_distance = kOrbThresholdLow;  // 50, ORB-SLAM TH_LOW
    o.ratio = 0.75;
    o.check_rotation = true;
    return o;
  }();
  solvers::Sim3Options sim3 = [] {
    solvers::Sim3Options o;
    o.ransac.threshold_px = 3.0;   // ~ sqrt(chi2(2, 0.99)=9.21) px at level 0
    o.ransac.max_iterations = 300;
    o.min_inliers = 20;
    return o;
  }();
  ProjectionMatchOptions guided = [] {
    ProjectionMatchOptions o;
    o.radius_px = 7.5;             // ORB-SLAM SearchBySim3
    o.max_distance = kOrbThresholdHigh;
    o.ratio = 1.0;                 // no ratio test, mutual consistency instead
    o.levels_below = 1;
    o.levels_above = 1;
    return o;
  }();
  int min_bow_matches = 20;        ///< CCM-SLAM: >= 20 BoW matches
  int min_inliers = 20;            ///< CCM-SLAM: >= 20 Sim(3) inliers (after the refinement)
  /// Inliers the first RANSAC on the BoW matches needs to seed the guided search; the
  /// refined Sim(3) still needs min_inliers, the guided search min_total_matches. Another
  /// agent's view of a weakly textured place gives 20-35 BoW matches, of which 20 are rarely
  /// all inliers (CCM-SLAM asks 20 of both; docs/server.md "Why overlaps went unfused").
  int min_seed_inliers = 12;
  int min_total_matches = 40;      ///< CCM-SLAM: >= 40 matches after guided search
  int refine_rounds = 1;           ///< RANSAC + guided search repetitions on the enlarged set
  /// Reprojection optimisation of the Sim(3) (sim3_refinement.h). Off by default: ~4x the
  /// verification time and it lets slightly more aliased views through (docs/place-recognition.md).
  bool optimize = false;
  Sim3RefineOptions optimization;
  /// Spatial support (see VerificationResult::spatial_support): grid cells per image side,
  /// projected points a cell needs to be tested, matched share that supports it.
  int support_grid = 4;
  int support_min_points = 8;
  double support_min_match_ratio = 0.2;
  double min_spatial_support = 0.8;  ///< reject below this, in [0, 1] (0 disables)
  std::string Validate() const;
};

/// Where a verification stopped, in pipeline order (kAccepted if it passed every test).
enum class VerificationStage { kInput, kBowMatches, kRansac, kRefinement, kGuidedMatches, kSpatialSupport, kAccepted };
constexpr int kNumVerificationStages = static_cast<int>(VerificationStage::kAccepted) + 1;
const char* VerificationStageName(VerificationStage stage);

struct VerificationResult {
  bool accepted = false;
  VerificationStage stage = VerificationStage::kInput;
  std::string reason;              ///< why it was rejected (empty if accepted)
  Sim3 query_from_candidate;       ///< p_query = S * p_candidate (camera frames, map scales)
  int bow_matches = 0;
  int ransac_inliers = 0;          ///< of the BoW matches under the first Sim(3)
  int final_inliers = 0;           ///< 3D-3D inliers of the refined Sim(3)
  int total_matches = 0;           ///< consistent matches after guided search
  /// 3D points of both views that project into the other image under the final Sim(3);
  /// total_matches / projected is the match coverage.
  int projected = 0;
  /// Share of image regions where the projected points found matches (min over both views):
  /// low when only one object agrees, e.g. an identical crate in another place.
  double spatial_support = 0.0;
  /// index1 = candidate keypoint, index2 = query keypoint (the total_matches pairs).
  std::vector<FeatureMatch> matches;
};

/// Verifies that `candidate` shows the place `query` shows. Seeded: deterministic.
VerificationResult VerifyPlace(const VerificationView& candidate, const VerificationView& query,
                               const VerificationOptions& options = {});

}  // namespace ccm
