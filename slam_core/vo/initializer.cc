#include "slam_core/vo/initializer.h"

#include <algorithm>

#include "slam_core/map_ops/map_bundle_adjustment.h"
#include "slam_core/solvers/two_view_init.h"
#include "slam_core/vo/vo_matching.h"

namespace ccm {
namespace {

constexpr int kMinFeaturesForReference = 100;

// Monocular scale is arbitrary: fix it so the first keyframe's median depth is 1.
void NormalizeScale(Map* map, const KeyFrame& kf1, KeyFrame* kf2) {
  const double median = MedianSceneDepth(*map, kf1);
  if (median <= 0.0) return;
  const double s = 1.0 / median;
  const SE3 pose = kf2->world_from_cam();
  kf2->SetWorldFromCam(SE3(pose.rotation(), pose.translation() * s));
  for (const auto& mp : map->map_points()) mp->SetPosition(mp->position() * s);
}

}  // namespace

std::optional<InitializationResult> Initializer::AddFrame(const VoFrame& frame) {
  if (static_cast<int>(frame.size()) < kMinFeaturesForReference) {
    reference_.reset();
    return std::nullopt;
  }
  if (!reference_ || frame.index - reference_->index > shared_->options.init_max_frames) {
    reference_ = frame;
    search_centres_.clear();
    return std::nullopt;
  }
  auto result = TryInitialize(frame);
  return result;
}

std::optional<InitializationResult> Initializer::TryInitialize(const VoFrame& cur) {
  const VoOptions& o = shared_->options;
  const std::vector<int> matches = MatchForInitialization(*reference_, cur, o.init_window_px, &search_centres_);
  std::vector<Eigen::Vector3d> b1, b2;
  std::vector<std::pair<int, int>> pairs;
  for (size_t i = 0; i < matches.size(); ++i) {
    const int j = matches[i];
    if (j < 0 || reference_->bearings[i].isZero() || cur.bearings[j].isZero()) continue;
    b1.push_back(reference_->bearings[i]);
    b2.push_back(cur.bearings[j]);
    pairs.emplace_back(static_cast<int>(i), j);
  }
  if (static_cast<int>(pairs.size()) < o.init_min_matches) {
    // Too few matches: the view changed too much; restart from this frame.
    reference_ = cur;
    search_centres_.clear();
    return std::nullopt;
  }
  solvers::TwoViewInitOptions init_options;
  init_options.focal_px = shared_->camera->intrinsics().fx;
  init_options.min_triangulated = o.init_min_map_points;
  init_options.min_parallax_deg = o.init_min_parallax_deg;
  init_options.min_homography_ratio = o.init_min_homography_ratio;
  init_options.count_distant_points = o.init_count_distant_points;
  init_options.min_rotation_residual_deg = o.init_min_rotation_residual_deg;
  init_options.min_motion_cost_gap =
      ambiguous_attempts_ < o.init_max_ambiguous_attempts ? o.init_min_motion_cost_gap : 0.0;
  solvers::TwoViewInitResult two_view = solvers::InitializeTwoView(b1, b2, init_options);
  ambiguous_attempts_ += two_view.status == solvers::SolverStatus::kAmbiguous && two_view.rival_angle_deg > 0.0;
  if (!two_view.ok() && o.init_fallback_homography_ratio < o.init_min_homography_ratio &&
      two_view.homography_ratio >= o.init_fallback_homography_ratio) {
    init_options.min_homography_ratio = o.init_fallback_homography_ratio;
    init_options.min_parallax_deg = std::max(o.init_min_parallax_deg, o.init_homography_min_parallax_deg);
    two_view = solvers::InitializeTwoView(b1, b2, init_options);
  }
  if (!two_view.ok() || two_view.num_triangulated < o.init_min_map_points) {
    // A view that looks planar, or whose matches are mostly distant (a road ahead), needs
    // the road profile to initialize soon.
    const bool planar = two_view.homography_ratio >= 0.40 && two_view.homography_ratio < o.init_min_homography_ratio;
    const bool distant =
        !o.init_count_distant_points && two_view.num_inliers > 0 && 3 * two_view.num_distant >= two_view.num_inliers;
    road_like_attempts_ += planar || distant;
    return std::nullopt;
  }

  InitializationResult r;
  r.map = std::make_shared<Map>(shared_->map_ids.Next(), o.map);
  r.kf1 = std::make_shared<KeyFrame>(shared_->kf_ids.Next(), reference_->stamp_ns, shared_->camera,
                                     reference_->features, shared_->pyramid, SE3::Identity());
  r.kf2 = std::make_shared<KeyFrame>(shared_->kf_ids.Next(), cur.stamp_ns, shared_->camera, cur.features,
                                     shared_->pyramid, two_view.cam2_from_cam1.inverse());
  r.map->AddKeyframe(r.kf1);
  r.map->AddKeyframe(r.kf2);
  for (size_t m = 0; m < pairs.size(); ++m) {
    if (!two_view.points_cam1[m]) continue;
    const auto [i, j] = pairs[m];
    auto mp = std::make_shared<MapPoint>(shared_->mp_ids.Next(), *two_view.points_cam1[m], r.kf1->id(),
                                         reference_->features->descriptors[i]);
    r.map->AddMapPoint(mp);
    r.map->AddObservation(r.kf1->id(), i, mp->id());
    r.map->AddObservation(r.kf2->id(), j, mp->id());
  }
  for (const auto& mp : r.map->map_points()) r.map->UpdateMapPointAppearance(mp->id());
  r.map->UpdateConnections(r.kf1->id());
  r.map->UpdateConnections(r.kf2->id());
  NormalizeScale(r.map.get(), *r.kf1, r.kf2.get());

  opt::BundleAdjusterOptions ba = opt::GlobalBaDefaults();
  ba.num_threads = 1;
  BundleAdjustKeyframes(r.map.get(), {r.kf2}, 1, ba, /*remove_outliers=*/true, nullptr);
  NormalizeScale(r.map.get(), *r.kf1, r.kf2.get());
  for (const auto& mp : r.map->map_points()) {
    if (mp->num_observations() < 2) r.map->EraseMapPoint(mp->id());
  }
  r.num_points = static_cast<int>(r.map->num_map_points());
  if (r.num_points < o.init_min_map_points) {
    Reset();
    return std::nullopt;
  }
  r.cur_matches.assign(cur.size(), nullptr);
  const auto kf2_points = r.kf2->map_points();
  for (size_t j = 0; j < kf2_points.size(); ++j) {
    if (kf2_points[j].valid()) r.cur_matches[j] = r.map->map_point(kf2_points[j]);
  }
  for (const auto& mp : r.map->map_points()) shared_->changes.Touch(mp->id());
  shared_->changes.Touch(r.kf1->id());
  shared_->changes.Touch(r.kf2->id());
  Reset();
  return r;
}

}  // namespace ccm
