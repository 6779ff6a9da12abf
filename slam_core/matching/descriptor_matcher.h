// Appearance-only matching between two descriptor sets: brute force, or restricted to
// candidate groups (e.g. the features of each bag-of-words vocabulary node, once the
// vocabulary exists), with Hamming threshold, ratio test, optional mutual check and optional
// rotation consistency. Stateless functions; safe from any thread.
#pragma once

#include <string>
#include <vector>

#include "slam_core/feature/orb_types.h"
#include "slam_core/matching/match_types.h"
#include "slam_core/matching/rotation_histogram.h"

namespace ccm {

struct DescriptorMatchOptions {
  int max_distance = kOrbThresholdLow;  ///< best Hamming distance must be <= this
  double ratio = 0.8;                   ///< best < ratio * second best (>= 1 disables the test)
  bool mutual = false;          ///< also require image 1's keypoint to be 2's best (cross check)
  bool check_rotation = false;  ///< rotation histogram (needs keypoints: FrameFeatures overload)
  RotationCheckOptions rotation;
  std::string Validate() const;
};

/// Matches descriptors1 to descriptors2; each index2 is used at most once (the best keeps it).
/// groups == nullptr: all pairs (brute force). options.check_rotation is ignored here.
std::vector<FeatureMatch> MatchDescriptors(const std::vector<OrbDescriptor>& descriptors1,
                                           const std::vector<OrbDescriptor>& descriptors2,
                                           const DescriptorMatchOptions& options,
                                           const MatchGroups* groups = nullptr);

/// Same on two images' features, with the rotation check when options.check_rotation.
std::vector<FeatureMatch> MatchFeatures(const FrameFeatures& features1,
                                        const FrameFeatures& features2,
                                        const DescriptorMatchOptions& options,
                                        const MatchGroups* groups = nullptr);

}  // namespace ccm
