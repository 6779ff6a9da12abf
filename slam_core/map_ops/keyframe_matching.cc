#include "slam_core/map_ops/keyframe_matching.h"

#include <algorithm>
#include <cmath>

#include "slam_core/matching/descriptor_matcher.h"
#include "slam_core/matching/epipolar_matcher.h"

namespace ccm {

std::optional<ProjectionCandidate> ProjectForMatching(const MapPoint& mp, const SE3& cam_from_world,
                                                      const Eigen::Vector3d& center_w, const CameraModel& camera,
                                                      const ScalePyramid& pyramid, bool check_view,
                                                      double min_view_cos) {
  const Eigen::Vector3d p_w = mp.position();
  const Eigen::Vector3d p_c = cam_from_world * p_w;
  Eigen::Vector2d uv;
  if (!camera.Project(p_c, &uv) || !camera.InImage(uv)) return std::nullopt;
  const Eigen::Vector3d ray = p_w - center_w;
  const double dist = ray.norm();
  ProjectionCandidate c;
  c.u = static_cast<float>(uv.x());
  c.v = static_cast<float>(uv.y());
  c.descriptor = mp.descriptor();
  c.level = mp.max_distance_m() > 0 ? mp.PredictLevel(dist, pyramid) : 0;
  if (check_view) {
    if (mp.max_distance_m() > 0 && (dist < 0.8 * mp.min_distance_m() || dist > 1.2 * mp.max_distance_m())) {
      return std::nullopt;
    }
    const double view_cos = ray.dot(mp.normal()) / std::max(dist, 1e-12);
    if (view_cos < min_view_cos) return std::nullopt;
    // ORB-SLAM: a wider window for oblique views, where the prediction is less certain.
    c.radius_factor = view_cos > 0.998 ? 2.5f : 4.0f;
  }
  return c;
}

std::vector<std::pair<int, int>> MatchForTriangulation(const KeyFrame& kf1, const KeyFrame& kf2,
                                                       const SE3& cam2_from_cam1) {
  auto taken = [](const KeyFrame& kf) {
    const auto mps = kf.map_points();
    std::vector<bool> skip(mps.size());
    for (size_t i = 0; i < mps.size(); ++i) skip[i] = mps[i].valid() || kf.bearing(i).isZero();
    return skip;
  };
  const std::vector<bool> skip1 = taken(kf1), skip2 = taken(kf2);
  EpipolarMatchOptions o;
  o.rad_per_px = 1.0 / kf2.camera().intrinsics().fx;
  const EpipolarView v1{kf1.features(), kf1.bearings(), &skip1};
  const EpipolarView v2{kf2.features(), kf2.bearings(), &skip2};
  std::vector<std::pair<int, int>> out;
  for (const FeatureMatch& m : MatchEpipolar(v1, v2, cam2_from_cam1, kf1.pyramid(), o)) {
    out.emplace_back(m.index1, m.index2);
  }
  return out;
}

std::vector<std::pair<std::shared_ptr<MapPoint>, int>> MatchPointsIntoKeyframe(
    const KeyFrame& kf, const KeypointGrid& grid, const std::vector<std::shared_ptr<MapPoint>>& points,
    double radius_px) {
  const SE3 cw = kf.cam_from_world();
  const Eigen::Vector3d center = kf.camera_center();
  std::vector<ProjectionCandidate> candidates;
  std::vector<int> point_of;
  for (size_t p = 0; p < points.size(); ++p) {
    if (points[p]->bad() || points[p]->KeypointIn(kf.id())) continue;
    const auto c = ProjectForMatching(*points[p], cw, center, kf.camera(), kf.pyramid(), true, 0.5);
    if (!c) continue;
    candidates.push_back(*c);
    point_of.push_back(static_cast<int>(p));
  }
  ProjectionMatchOptions o;
  o.radius_px = radius_px;
  o.max_distance = kOrbThresholdLow;
  o.ratio = 1.0;
  std::vector<std::pair<std::shared_ptr<MapPoint>, int>> out;
  for (const FeatureMatch& m : MatchByProjection(candidates, kf.features(), grid, kf.pyramid(), o)) {
    out.emplace_back(points[point_of[m.index1]], m.index2);
  }
  return out;
}

}  // namespace ccm
