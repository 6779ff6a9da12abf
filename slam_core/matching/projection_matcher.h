// Matching by projection: the caller predicts where known points (map points, or the
// keypoints of a previous frame) appear in a frame, and this finds the best keypoint around
// each prediction within a radius that grows with the predicted pyramid level. Input is plain
// values, so it does not depend on the map module. Stateless; safe from any thread.
#pragma once

#include <string>
#include <vector>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/matching/match_types.h"
#include "slam_core/matching/rotation_histogram.h"

namespace ccm {

/// One point to look for in the frame.
struct ProjectionCandidate {
  float u = 0, v = 0;  ///< predicted position, distorted level-0 pixels
  int level = 0;       ///< predicted pyramid level (from the predicted distance)
  OrbDescriptor descriptor{};
  float radius_factor = 1.f;  ///< multiplies the search radius (e.g. larger for oblique views)
};

struct ProjectionMatchOptions {
  double radius_px = 3.0;                ///< search half-width at level 0; times scale(level) [px]
  int max_distance = kOrbThresholdHigh;  ///< best Hamming distance must be <= this
  double ratio = 0.8;                    ///< best < ratio * second when both are on the same level
  int levels_below = 1;                  ///< keypoints from level - levels_below ...
  int levels_above = 0;                  ///< ... to level + levels_above are searched
  bool check_rotation = false;           ///< needs candidate_angles_deg in the call
  RotationCheckOptions rotation;
  std::string Validate() const;
};

/// Returns candidate -> keypoint matches (index1 = candidate, index2 = keypoint). Each keypoint
/// is used at most once (the candidate with the smallest distance keeps it). Keypoints with
/// keypoint_taken[k] (optional, size == features.size()) are skipped, e.g. those already
/// associated. With options.check_rotation, candidate_angles_deg[c] is the candidate's
/// keypoint angle in the image it was described in (e.g. the previous frame).
std::vector<FeatureMatch> MatchByProjection(
    const std::vector<ProjectionCandidate>& candidates, const FrameFeatures& features,
    const KeypointGrid& grid, const ScalePyramid& pyramid, const ProjectionMatchOptions& options,
    const std::vector<bool>* keypoint_taken = nullptr,
    const std::vector<float>* candidate_angles_deg = nullptr);

}  // namespace ccm
