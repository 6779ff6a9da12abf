// Rotation-consistency check of ORB-SLAM: between two images all correct matches rotate by
// about the same in-plane angle, so matches are binned by their keypoint angle change and only
// the (up to) three most populated bins survive. Cheap, and removes many wrong matches that
// passed the descriptor test. Used by every matcher; stateless.
#pragma once

#include <string>
#include <vector>

#include "slam_core/feature/orb_types.h"
#include "slam_core/matching/match_types.h"

namespace ccm {

struct RotationCheckOptions {
  int num_bins = 30;           ///< histogram bins over 360 deg
  int keep_bins = 3;           ///< most populated bins kept
  double min_bin_ratio = 0.1;  ///< a kept bin (but the first) needs this share of the largest
  std::string Validate() const;
};

/// keep[k] is true when angle_change_deg[k] (any value, wrapped to [0, 360)) falls into one of
/// the kept bins. Deterministic: equal bins are ranked by bin index.
std::vector<bool> RotationConsistentMask(const std::vector<float>& angle_change_deg,
                                         const RotationCheckOptions& options);

/// Removes matches[k] when angle_change_deg[k] is inconsistent (sizes must agree; else no-op).
void FilterByAngleChange(const std::vector<float>& angle_change_deg,
                         const RotationCheckOptions& options, std::vector<FeatureMatch>* matches);

/// Removes matches whose angle change keypoints2[index2].angle - keypoints1[index1].angle is
/// inconsistent. Order of the survivors is kept.
void FilterByRotation(const std::vector<Keypoint>& keypoints1,
                      const std::vector<Keypoint>& keypoints2, const RotationCheckOptions& options,
                      std::vector<FeatureMatch>* matches);

}  // namespace ccm
