// Matching on keyframes and map points, shared by the agent's VO and the server (mapping,
// loop closing, map fusion), implemented with the value-type matchers of ccm_matching.
// Stateless; any thread.
#pragma once

#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/map/keyframe.h"
#include "slam_core/map/map_point.h"
#include "slam_core/matching/projection_matcher.h"

namespace ccm {

/// Candidate for matching map point `mp` seen from camera pose cam_from_world (camera centre
/// center_w), or nullopt when it is behind the camera, outside the image, or (with
/// check_view) outside its depth range or seen at an angle whose cosine to its mean normal is
/// below min_view_cos.
std::optional<ProjectionCandidate> ProjectForMatching(const MapPoint& mp, const SE3& cam_from_world,
                                                      const Eigen::Vector3d& center_w, const CameraModel& camera,
                                                      const ScalePyramid& pyramid, bool check_view,
                                                      double min_view_cos);

/// Triangulation: keypoint pairs (i in kf1, j in kf2) without map points that satisfy the
/// epipolar constraint of cam2_from_cam1.
std::vector<std::pair<int, int>> MatchForTriangulation(const KeyFrame& kf1, const KeyFrame& kf2,
                                                       const SE3& cam2_from_cam1);

/// Fusion: projects `points` into keyframe `kf` (whose keypoints `grid` indexes) and returns
/// (point, keypoint index) pairs within radius_px * level scale that match in appearance
/// (whether or not the keypoint already has a point).
std::vector<std::pair<std::shared_ptr<MapPoint>, int>> MatchPointsIntoKeyframe(
    const KeyFrame& kf, const KeypointGrid& grid, const std::vector<std::shared_ptr<MapPoint>>& points,
    double radius_px);

}  // namespace ccm
