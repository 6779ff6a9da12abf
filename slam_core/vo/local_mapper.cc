#include "slam_core/vo/local_mapper.h"

#include <algorithm>
#include <cmath>

#include "slam_core/map_ops/keyframe_matching.h"
#include "slam_core/map_ops/map_bundle_adjustment.h"
#include "slam_core/map_ops/point_fusion.h"
#include "slam_core/solvers/triangulation.h"
#include "slam_core/vo/server_data_integrator.h"
#include "slam_core/vo/vo_matching.h"

namespace ccm {
namespace {

constexpr double kMinFoundRatio = 0.25;  // ORB-SLAM: points found in < 25% of predictions go

}  // namespace

LocalMapper::LocalMapper(VoShared* shared, const AckSource* acks)
    : shared_(shared), acks_(acks), bound_(shared->agent, shared->options.bound) {}

void LocalMapper::Process(const KeyframeJob& job) {
  Map* map = job.map.get();
  if (map->id() != current_map_) {
    current_map_ = map->id();
    recent_points_.clear();
  }
  ++kf_counter_;
  InsertKeyframe(map, job);
  if (!job.already_in_map) {
    CullRecentPoints(map);
    TriangulateNewPoints(map, job.keyframe);
    FuseDuplicates(map, job.keyframe);
    LocalBundleAdjustment(map, job.keyframe);
    CullRedundantKeyframes(map, job.keyframe);
  }
  // Remember poses of keyframes that trimming is about to remove.
  const std::vector<std::shared_ptr<KeyFrame>> kfs = map->keyframes();
  bound_.Trim(map, job.keyframe->id(), *acks_);
  for (const auto& kf : kfs) {
    if (!map->keyframe(kf->id())) Retire(kf);
  }
  ++stats_.keyframes_processed;
}

void LocalMapper::ApplyServerData(Map* map, const ServerMapData& data) {
  IntegrateServerData(data, shared_->agent, shared_->pyramid, map, &bound_, &server_stats_);
  std::vector<KeyframeId> shared_kfs;
  for (const ServerKeyframe& kf : data.keyframes) {
    if (kf.id.agent() != shared_->agent && map->keyframe(kf.id)) shared_kfs.push_back(kf.id);
  }
  shared_->neighbourhood.Set(std::move(shared_kfs));
}

void LocalMapper::Retire(const std::shared_ptr<KeyFrame>& kf) {
  if (!shared_->options.record_frame_trajectory) return;  // unbounded flights keep no history
  retired_.push_back({kf->id(), {kf->stamp_ns(), kf->world_from_cam()}});
}

void LocalMapper::InsertKeyframe(Map* map, const KeyframeJob& job) {
  const auto& kf = job.keyframe;
  if (!job.already_in_map) {
    map->AddKeyframe(kf);
    for (size_t i = 0; i < job.matches.size(); ++i) {
      const auto& mp = job.matches[i];
      if (!mp || mp->bad() || !map->map_point(mp->id())) continue;
      if (map->AddObservation(kf->id(), static_cast<int>(i), mp->id())) {
        map->UpdateMapPointAppearance(mp->id());
        shared_->changes.Touch(mp->id());
      }
    }
    map->UpdateConnections(kf->id());
  }
  bound_.OnKeyframeInserted(kf->id());
  shared_->changes.Touch(kf->id());
}

void LocalMapper::CullRecentPoints(Map* map) {
  for (auto it = recent_points_.begin(); it != recent_points_.end();) {
    const auto mp = map->map_point(it->first);
    const int64_t age = kf_counter_ - it->second;
    bool drop = false;
    if (!mp || mp->bad()) {
      drop = true;
    } else if (mp->found_ratio() < kMinFoundRatio || (age >= 2 && mp->num_observations() <= 2)) {
      map->EraseMapPoint(mp->id());
      ++stats_.points_culled;
      drop = true;
    } else if (age >= 3) {
      drop = true;  // survived its probation
    }
    it = drop ? recent_points_.erase(it) : std::next(it);
  }
}

void LocalMapper::TriangulateNewPoints(Map* map, const std::shared_ptr<KeyFrame>& kf) {
  const VoOptions& o = shared_->options;
  const SE3 kf_wc = kf->world_from_cam();
  solvers::TriangulationOptions tri;
  tri.focal_px = kf->camera().intrinsics().fx;
  // Parallax each pyramid level needs, as a cosine: once per keyframe, not per match.
  const double min_cos = std::cos(o.min_triangulation_parallax_deg * M_PI / 180.0);
  std::vector<double> max_cos_at_level(kf->pyramid().scale.size());
  for (size_t l = 0; l < max_cos_at_level.size(); ++l) {
    max_cos_at_level[l] = std::min(min_cos, std::cos(o.triangulation_parallax_sigmas * kf->pyramid().scale[l] / tri.focal_px));
  }
  // Widest baseline first: a keypoint matched in several neighbours becomes a point from the
  // best-conditioned pair. In covisibility order the nearest neighbour comes first, and a
  // point triangulated there at barely the minimum parallax keeps that short baseline's
  // depth error (docs/vo.md "Widest baseline first").
  struct Neighbour {
    double baseline;
    std::shared_ptr<KeyFrame> kf;
  };
  std::vector<Neighbour> neighbours;
  for (const KeyframeId nid : kf->BestCovisible(o.triangulation_neighbours)) {
    auto n = map->keyframe(nid);
    if (n && !n->bad()) neighbours.push_back({(n->camera_center() - kf_wc.translation()).norm(), std::move(n)});
  }
  if (o.triangulate_widest_baseline_first) {
    std::stable_sort(neighbours.begin(), neighbours.end(), [](const Neighbour& a, const Neighbour& b) { return a.baseline > b.baseline; });
  }
  for (const auto& [baseline, n] : neighbours) {
    const KeyframeId nid = n->id();
    const double depth = MedianSceneDepth(*map, *n);
    if (baseline / (depth > 0.0 ? depth : 1.0) < o.min_baseline_depth_ratio) continue;
    const SE3 n_from_kf = n->cam_from_world() * kf_wc;
    for (const auto& [i, j] : MatchForTriangulation(*kf, *n, n_from_kf)) {
      if (kf->MapPointAt(i).valid() || n->MapPointAt(j).valid()) continue;
      const int level = std::max(kf->features().keypoints[i].level, n->features().keypoints[j].level);
      tri.max_error_px = 2.45 * kf->pyramid().scale[level];
      tri.max_cos_parallax = max_cos_at_level[level];
      const auto r = solvers::TriangulateTwoView(kf->bearing(i), n->bearing(j), n_from_kf, tri);
      if (!r.ok()) continue;
      const Eigen::Vector3d p_w = kf_wc * *r.point;
      auto mp = std::make_shared<MapPoint>(shared_->mp_ids.Next(), p_w, kf->id(), kf->features().descriptors[i]);
      map->AddMapPoint(mp);
      map->AddObservation(kf->id(), i, mp->id());
      map->AddObservation(nid, j, mp->id());
      map->UpdateMapPointAppearance(mp->id());
      recent_points_.emplace_back(mp->id(), kf_counter_);
      shared_->changes.Touch(mp->id());
      ++stats_.points_created;
    }
  }
}

void LocalMapper::FuseDuplicates(Map* map, const std::shared_ptr<KeyFrame>& kf) {
  const auto targets = kf->BestCovisible(shared_->options.fusion_neighbours);
  PointFusionResult fusion;
  // One grid per keyframe: the new keyframe's serves all neighbours' points.
  const auto own = PointsOf(*map, *kf);
  for (const KeyframeId t : targets) {
    if (const auto target = map->keyframe(t)) FusePointsIntoKeyframe(map, target, GridOf(*target), own, 3.0, &fusion);
  }
  const KeypointGrid kf_grid = GridOf(*kf);
  for (const KeyframeId t : targets) {
    if (const auto target = map->keyframe(t)) FusePointsIntoKeyframe(map, kf, kf_grid, PointsOf(*map, *target), 3.0, &fusion);
  }
  stats_.points_fused += fusion.fused;
  for (const auto& mp : PointsOf(*map, *kf)) map->UpdateMapPointAppearance(mp->id());
  map->UpdateConnections(kf->id());
}

void LocalMapper::LocalBundleAdjustment(Map* map, const std::shared_ptr<KeyFrame>& kf) {
  std::vector<std::shared_ptr<KeyFrame>> window{kf};
  for (const KeyframeId id : kf->BestCovisible(shared_->options.local_ba_window - 1)) {
    if (const auto n = map->keyframe(id); n && !n->bad()) window.push_back(n);
  }
  // The segment's first keyframe anchors the gauge: never move it.
  const auto all = map->keyframes();
  if (!all.empty()) {
    window.erase(std::remove_if(window.begin(), window.end(),
                                [&](const auto& k) { return k->id() == all.front()->id(); }),
                 window.end());
  }
  if (window.empty()) return;
  opt::BundleAdjusterOptions ba = opt::LocalBaDefaults();
  ba.num_threads = 1;
  BundleAdjustKeyframes(map, window, shared_->options.local_ba_max_fixed, ba, true, &shared_->changes);
}

void LocalMapper::CullRedundantKeyframes(Map* map, const std::shared_ptr<KeyFrame>& kf) {
  const auto all = map->keyframes();
  if (all.size() < 3) return;
  const KeyframeId first = all.front()->id();
  for (const KeyframeId nid : kf->BestCovisible(-1)) {
    if (nid == first || nid.agent() != shared_->agent) continue;
    const auto n = map->keyframe(nid);
    if (!n) continue;
    int valid = 0, redundant = 0;
    const auto mps = n->map_points();
    for (size_t i = 0; i < mps.size(); ++i) {
      if (!mps[i].valid()) continue;
      const auto mp = map->map_point(mps[i]);
      if (!mp) continue;
      ++valid;
      const int level = n->features().keypoints[i].level;
      int others = 0;
      for (const auto& [okf, oidx] : mp->observations()) {
        if (okf == nid) continue;
        const auto o = map->keyframe(okf);
        if (o && o->features().keypoints[oidx].level <= level + 1) ++others;
        if (others >= 3) break;
      }
      redundant += others >= 3;
    }
    if (valid > 0 && redundant > shared_->options.redundant_kf_ratio * valid) {
      Retire(n);
      map->EraseKeyframe(nid);
      ++stats_.keyframes_culled;
    }
  }
}

}  // namespace ccm
