#include "slam_core/map_ops/map_bundle_adjustment.h"

#include <algorithm>
#include <unordered_map>
#include <unordered_set>

namespace ccm {
namespace {

struct ProblemIndex {
  opt::BundleProblem problem;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::vector<std::shared_ptr<MapPoint>> points;
  std::unordered_map<KeyframeId, int> kf_index;
  std::unordered_map<const CameraModel*, int> camera_index;

  int AddKeyframe(const std::shared_ptr<KeyFrame>& kf, bool fixed) {
    const auto [it, inserted] = kf_index.emplace(kf->id(), static_cast<int>(kfs.size()));
    if (!inserted) return it->second;
    const auto cam = camera_index.emplace(&kf->camera(), static_cast<int>(problem.cameras.size()));
    if (cam.second) problem.cameras.push_back(kf->camera_ptr());
    opt::PoseBlock pose;
    pose.id = kf->id().packed();
    pose.world_from_cam = kf->world_from_cam();
    pose.fixed = fixed;
    pose.camera_index = cam.first->second;
    problem.poses.push_back(pose);
    kfs.push_back(kf);
    return it->second;
  }
};

}  // namespace

MapBaReport BundleAdjustKeyframes(Map* map, const std::vector<std::shared_ptr<KeyFrame>>& free_kfs,
                                  int max_fixed, const opt::BundleAdjusterOptions& options,
                                  bool remove_outliers, ChangeLog* changes, bool update_appearance) {
  ProblemIndex ix;
  MapBaReport report;
  for (const auto& kf : free_kfs) ix.AddKeyframe(kf, false);
  // Points seen by the free keyframes, and how often each other keyframe sees them.
  std::unordered_set<MapPointId> seen;
  std::unordered_map<KeyframeId, int> periphery;
  for (const auto& kf : free_kfs) {
    for (const MapPointId id : kf->map_points()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      const auto mp = map->map_point(id);
      if (!mp || mp->bad()) continue;
      ix.points.push_back(mp);
      for (const auto& [other, idx] : mp->observations()) {
        if (!ix.kf_index.count(other)) ++periphery[other];
      }
    }
  }
  std::vector<std::pair<int, KeyframeId>> ranked;
  for (const auto& [id, n] : periphery) ranked.emplace_back(n, id);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  for (const auto& [n, id] : ranked) {
    if (static_cast<int>(ix.kfs.size()) - static_cast<int>(free_kfs.size()) >= max_fixed) break;
    if (const auto kf = map->keyframe(id)) ix.AddKeyframe(kf, true);
  }
  struct ObsRef {
    int kf, point;
  };
  std::vector<ObsRef> refs;
  for (size_t p = 0; p < ix.points.size(); ++p) {
    const auto& mp = ix.points[p];
    opt::PointBlock block;
    block.id = mp->id().packed();
    block.position_w = mp->position();
    ix.problem.points.push_back(block);
    for (const auto& [kf_id, idx] : mp->observations()) {
      const auto it = ix.kf_index.find(kf_id);
      if (it == ix.kf_index.end()) continue;
      const Keypoint& kp = ix.kfs[it->second]->features().keypoints[idx];
      opt::Observation o;
      o.pose_index = it->second;
      o.point_index = static_cast<int>(p);
      o.uv_px = Eigen::Vector2d(kp.u, kp.v);
      o.sigma_px = ix.kfs[it->second]->pyramid().scale[kp.level];
      ix.problem.observations.push_back(o);
      refs.push_back({it->second, static_cast<int>(p)});
    }
  }
  report.num_free_keyframes = static_cast<int>(free_kfs.size());
  report.num_fixed_keyframes = static_cast<int>(ix.kfs.size() - free_kfs.size());
  report.num_points = static_cast<int>(ix.points.size());
  if (ix.problem.observations.empty()) return report;
  report.summary = opt::BundleAdjust(&ix.problem, options);
  if (!report.summary.usable) return report;
  for (size_t k = 0; k < ix.kfs.size(); ++k) {
    if (ix.problem.poses[k].fixed) continue;
    ix.kfs[k]->SetWorldFromCam(ix.problem.poses[k].world_from_cam);
    if (changes) changes->Touch(ix.kfs[k]->id());
  }
  for (size_t p = 0; p < ix.points.size(); ++p) {
    ix.points[p]->SetPosition(ix.problem.points[p].position_w);
    if (changes) changes->Touch(ix.points[p]->id());
  }
  std::vector<bool> changed(ix.points.size(), update_appearance);
  if (remove_outliers) {
    for (size_t i = 0; i < refs.size(); ++i) {
      if (report.summary.inlier[i]) continue;
      map->EraseObservation(ix.kfs[refs[i].kf]->id(), ix.points[refs[i].point]->id());
      changed[refs[i].point] = true;
      ++report.outliers_removed;
    }
  }
  for (size_t p = 0; p < ix.points.size(); ++p) {
    if (changed[p] && !ix.points[p]->bad()) map->UpdateMapPointAppearance(ix.points[p]->id());
  }
  return report;
}

std::vector<opt::PointObservation> LinkedPointObservations(const Map& map, const KeyFrame& kf,
                                                           std::vector<MapPointId>* points) {
  std::vector<opt::PointObservation> obs;
  const auto mps = kf.map_points();
  for (size_t i = 0; i < mps.size(); ++i) {
    if (!mps[i].valid()) continue;
    const auto mp = map.map_point(mps[i]);
    if (!mp || mp->bad()) continue;
    const Keypoint& k = kf.features().keypoints[i];
    obs.push_back({mp->position(), Eigen::Vector2d(k.u, k.v), kf.pyramid().scale[k.level]});
    if (points) points->push_back(mps[i]);
  }
  return obs;
}

}  // namespace ccm
