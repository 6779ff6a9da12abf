// Common result type and descriptor thresholds of the ORB matchers.
#pragma once

#include <vector>

namespace ccm {

/// Hamming thresholds of ORB-SLAM: a strict one for new associations (triangulation,
/// initialization) and a loose one for tracking known map points.
constexpr int kOrbThresholdLow = 50;
constexpr int kOrbThresholdHigh = 100;

/// One association. For two-image matchers index1/index2 are keypoint indices in image 1/2;
/// for matching by projection index1 is the candidate index and index2 the keypoint index.
struct FeatureMatch {
  int index1 = -1;
  int index2 = -1;
  int distance = 0;  ///< Hamming distance of the descriptors
};

/// Candidate pairs per group: index1 in groups1[g] may only match index2 in groups2[g]
/// (e.g. the features of each bag-of-words vocabulary node). Groups should be disjoint;
/// groups beyond the shorter of the two lists are ignored.
struct MatchGroups {
  std::vector<std::vector<int>> groups1, groups2;
};

}  // namespace ccm
