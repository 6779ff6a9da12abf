// Matching for monocular initialization (ORB-SLAM's SearchForInitialization): the first frame's
// finest-level keypoints are searched in a window around where they were last matched in the
// following frames, with a strict descriptor threshold, a 0.9 ratio test and the rotation
// check. The caller keeps the per-keypoint search centres across frames. Stateless.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/matching/match_types.h"
#include "slam_core/matching/rotation_histogram.h"

namespace ccm {

struct WindowMatchOptions {
  float window_px = 100.f;              ///< search half-width around the last position [px]
  int max_distance = kOrbThresholdLow;  ///< best Hamming distance must be <= this
  double ratio = 0.9;                   ///< best < ratio * second
  int max_level = 0;                    ///< only keypoints up to this level (0: finest only)
  bool check_rotation = true;
  RotationCheckOptions rotation;
  std::string Validate() const;
};

/// Matches features1 (the initial frame) into features2 (indexed by grid2). search_centres[i] is
/// where keypoint i of frame 1 is searched (initially its own position, see
/// InitialSearchCentres); it is moved to the matched position for the next frame. Returns
/// matches index1 -> index2, one-to-one (the smaller distance wins), sorted by index1.
std::vector<FeatureMatch> MatchInWindow(const FrameFeatures& features1,
                                        const FrameFeatures& features2, const KeypointGrid& grid2,
                                        const WindowMatchOptions& options,
                                        std::vector<Eigen::Vector2f>* search_centres);

/// Search centres for a new initial frame: each keypoint's own position.
std::vector<Eigen::Vector2f> InitialSearchCentres(const FrameFeatures& features1);

}  // namespace ccm
