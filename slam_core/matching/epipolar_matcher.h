// Guided matching between two keyframes with a known relative pose, for triangulating new
// map points (ORB-SLAM's SearchForTriangulation). Works on unit bearing vectors, so any
// camera model works: the caller unprojects each keypoint. A pair is accepted when bearing2
// lies within an angular band around the epipolar plane of bearing1, the band width derived
// from keypoint 2's pyramid level. Candidate pairs: brute force, or per group (bag-of-words
// nodes, when a vocabulary exists). Stateless; safe from any thread.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/se3.h"
#include "slam_core/matching/descriptor_matcher.h"
#include "slam_core/matching/match_types.h"
#include "slam_core/matching/rotation_histogram.h"

namespace ccm {

struct EpipolarMatchOptions {
  int max_distance = kOrbThresholdLow;  ///< best Hamming distance must be <= this
  double ratio = 0.8;                   ///< best < ratio * second among epipolar-consistent pairs
  /// Angle subtended by one level-0 pixel [rad], e.g. 1 / fx of a pinhole camera. Converts the
  /// pixel noise of a level into an angular band. Required (> 0).
  double rad_per_px = 0.0;
  double chi2_threshold = 3.84;  ///< (angle / (sigma(level2) rad_per_px))^2 below this (95%, 1 dof)
  /// Bearings2 closer than this to the epipole (the baseline direction) are skipped: their
  /// point would have almost no parallax. [px at level 0, times scale(level2)]
  double min_epipole_distance_px = 10.0;
  bool check_rotation = true;
  RotationCheckOptions rotation;
  std::string Validate() const;
};

/// One keyframe's side of the problem. bearings[k] is the unit bearing of keypoint k in the
/// keyframe's camera frame; skip (optional) marks keypoints not to match (already associated).
struct EpipolarView {
  const FrameFeatures& features;
  const std::vector<Eigen::Vector3d>& bearings;
  const std::vector<bool>* skip = nullptr;
};

/// Matches view1 to view2 given cam2_from_cam1. Each keypoint is used at most once. Returns
/// nothing when the inputs are inconsistent (bearings size) or the baseline is zero (no
/// epipolar geometry: pure rotation cannot triangulate).
std::vector<FeatureMatch> MatchEpipolar(const EpipolarView& view1, const EpipolarView& view2,
                                        const SE3& cam2_from_cam1, const ScalePyramid& pyramid,
                                        const EpipolarMatchOptions& options,
                                        const MatchGroups* groups = nullptr);

/// Angle [rad] between bearing2 and the epipolar plane of bearing1 (0 for a perfect match).
double EpipolarAngle(const Eigen::Vector3d& bearing1, const Eigen::Vector3d& bearing2,
                     const SE3& cam2_from_cam1);

}  // namespace ccm
