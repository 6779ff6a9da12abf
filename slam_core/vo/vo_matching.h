// The VO's matching steps expressed on its own data (frames, keyframes, map points),
// implemented with the value-type matchers of ccm_matching. Stateless; any thread.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include "slam_core/map/keyframe.h"
#include "slam_core/vo/vo_frame.h"

namespace ccm {

/// Projects `points` with the frame's current pose and matches them to its keypoints
/// that have no point yet (search radius radius_px * level scale). With
/// check_view_geometry, points outside their depth range or seen at an angle whose cosine
/// to their mean normal is below min_view_cos are skipped (tracking of the local map).
/// Sets frame->map_points; returns the number of new matches.
int SearchMapPointsByProjection(VoFrame* frame, const std::vector<std::shared_ptr<MapPoint>>& points,
                                const CameraModel& camera, const ScalePyramid& pyramid, double radius_px,
                                bool check_view_geometry, double min_view_cos);

/// Monocular initialization: for each keypoint of `ref` the matching keypoint of `cur`
/// within window_px of where it was last matched (search_centres, kept by the caller
/// across frames; reset when its size differs from ref's), or -1.
std::vector<int> MatchForInitialization(const VoFrame& ref, const VoFrame& cur, double window_px,
                                        std::vector<Eigen::Vector2f>* search_centres);

/// Relocalization: appearance matches between the frame's keypoints and `points`
/// (keypoint index, point).
std::vector<std::pair<int, std::shared_ptr<MapPoint>>> MatchFrameToPoints(
    const VoFrame& frame, const std::vector<std::shared_ptr<MapPoint>>& points);

}  // namespace ccm
