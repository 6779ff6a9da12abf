#include "slam_core/vo/vo_matching.h"

#include <cmath>

#include "slam_core/matching/descriptor_matcher.h"
#include "slam_core/matching/epipolar_matcher.h"
#include "slam_core/matching/projection_matcher.h"
#include "slam_core/matching/window_matcher.h"

namespace ccm {
namespace {

// Candidate for a map point seen from camera pose cam_from_world, or nullopt when it is
// behind the camera, outside the image, or (with view checks) outside its depth range or
// seen from too oblique an angle.
std::optional<ProjectionCandidate> ProjectPoint(const MapPoint& mp, const SE3& cam_from_world,
                                                const Eigen::Vector3d& center_w, const CameraModel& camera,
                                                const ScalePyramid& pyramid, bool check_view, double min_view_cos) {
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

}  // namespace

int SearchMapPointsByProjection(VoFrame* frame, const std::vector<std::shared_ptr<MapPoint>>& points,
                                const CameraModel& camera, const ScalePyramid& pyramid, double radius_px,
                                bool check_view_geometry, double min_view_cos) {
  const SE3 cw = frame->cam_from_world();
  const Eigen::Vector3d center = frame->world_from_cam.translation();
  std::vector<ProjectionCandidate> candidates;
  std::vector<int> point_of;
  for (size_t p = 0; p < points.size(); ++p) {
    if (points[p]->bad()) continue;
    const auto c = ProjectPoint(*points[p], cw, center, camera, pyramid, check_view_geometry, min_view_cos);
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
    const auto c = ProjectPoint(*points[p], cw, center, kf.camera(), kf.pyramid(), true, 0.5);
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
