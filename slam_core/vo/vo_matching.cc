#include "slam_core/vo/vo_matching.h"

#include <cmath>

#include "slam_core/map_ops/keyframe_matching.h"
#include "slam_core/matching/descriptor_matcher.h"
#include "slam_core/matching/projection_matcher.h"
#include "slam_core/matching/window_matcher.h"

namespace ccm {
int SearchMapPointsByProjection(VoFrame* frame, const std::vector<std::shared_ptr<MapPoint>>& points,
                                const CameraModel& camera, const ScalePyramid& pyramid, double radius_px,
                                bool check_view_geometry, double min_view_cos) {
  const SE3 cw = frame->cam_from_world();
  const Eigen::Vector3d center = frame->world_from_cam.translation();
  std::vector<ProjectionCandidate> candidates;
  std::vector<int> point_of;
  for (size_t p = 0; p < points.size(); ++p) {
    if (points[p]->bad()) continue;
    const auto c = ProjectForMatching(*points[p], cw, center, camera, pyramid, check_view_geometry, min_view_cos);
    if (!c) continue;
    if (check_view_geometry) points[p]->IncreaseVisible();
    candidates.push_back(*c);
    point_of.push_back(static_cast<int>(p));
  }
  std::vector<bool> taken(frame->size());
  for (size_t i = 0; i < frame->size(); ++i) taken[i] = frame->map_points[i] != nullptr;
  ProjectionMatchOptions o;
  o.radius_px = radius_px;
  o.levels_below = 1;
  o.levels_above = 1;
  int n = 0;
  for (const FeatureMatch& m : MatchByProjection(candidates, *frame->features, *frame->grid, pyramid, o, &taken)) {
    frame->map_points[m.index2] = points[point_of[m.index1]];
    frame->outlier[m.index2] = false;
    ++n;
  }
  return n;
}

std::vector<int> MatchForInitialization(const VoFrame& ref, const VoFrame& cur, double window_px,
                                        std::vector<Eigen::Vector2f>* search_centres) {
  if (search_centres->size() != ref.size()) *search_centres = InitialSearchCentres(*ref.features);
  WindowMatchOptions o;
  o.window_px = static_cast<float>(window_px);
  std::vector<int> out(ref.size(), -1);
  for (const FeatureMatch& m : MatchInWindow(*ref.features, *cur.features, *cur.grid, o, search_centres)) {
    out[m.index1] = m.index2;
  }
  return out;
}

std::vector<std::pair<int, std::shared_ptr<MapPoint>>> MatchFrameToPoints(
    const VoFrame& frame, const std::vector<std::shared_ptr<MapPoint>>& points) {
  std::vector<OrbDescriptor> descs;
  std::vector<std::shared_ptr<MapPoint>> live;
  for (const auto& mp : points) {
    if (mp->bad()) continue;
    descs.push_back(mp->descriptor());
    live.push_back(mp);
  }
  DescriptorMatchOptions o;
  o.max_distance = kOrbThresholdLow;
  o.ratio = 0.75;
  std::vector<std::pair<int, std::shared_ptr<MapPoint>>> out;
  for (const FeatureMatch& m : MatchDescriptors(descs, frame.features->descriptors, o)) {
    if (!frame.bearings[m.index2].isZero()) out.emplace_back(m.index2, live[m.index1]);
  }
  return out;
}

}  // namespace ccm
