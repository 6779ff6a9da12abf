#include "slam_core/vo/tracker.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/solvers/absolute_pose.h"
#include "slam_core/vo/vo_matching.h"

namespace ccm {

const char* TrackingStateName(TrackingState state) {
  switch (state) {
    case TrackingState::kInitializing: return "initializing";
    case TrackingState::kTracking: return "tracking";
    case TrackingState::kLost: return "lost";
  }
  return "?";
}

namespace {

// Angle between the rays of the left and right edge pixels of the middle row (pinhole and
// fisheye alike); 0 if the camera cannot unproject them.
double HorizontalFov(const CameraModel& camera) {
  const CameraIntrinsics& k = camera.intrinsics();
  Eigen::Vector3d left, right;
  if (!camera.Unproject(Eigen::Vector2d(0.0, k.cy), &left) ||
      !camera.Unproject(Eigen::Vector2d(k.width_px - 1.0, k.cy), &right)) {
    return 0.0;
  }
  return std::acos(std::clamp(left.normalized().dot(right.normalized()), -1.0, 1.0));
}

}  // namespace

Tracker::Tracker(VoShared* shared, KeyframeSink sink, std::function<bool()> mapper_idle)
    : shared_(shared),
      sink_(std::move(sink)),
      mapper_idle_(std::move(mapper_idle)),
      initializer_(shared),
      horizontal_fov_rad_(shared->camera ? HorizontalFov(*shared->camera) : 0.0) {}

TrackingResult Tracker::Track(VoFrame frame) {
  TrackingResult result;
  if (state_ == TrackingState::kInitializing) {
    if (auto init = initializer_.AddFrame(frame)) {
      frame.world_from_cam = init->kf2->world_from_cam();
      frame.map_points = init->cur_matches;
      OnInitialized(*init);
      RememberKeyframeFrame(frame);
      result.world_from_cam = frame.world_from_cam;
      result.inliers = frame.NumMatched();
      result.new_keyframe = true;
      last_by_motion_model_ = false;
      last_frame_ = std::move(frame);
    }
    result.state = state_;
    result.segment = map_ ? map_->id() : MapId::Invalid();
    return result;
  }

  bool ok = false;
  bool by_motion_model = false;
  if (state_ == TrackingState::kTracking) {
    by_motion_model = velocity_ && TrackWithMotionModel(&frame);
    ok = by_motion_model || TrackReferenceKeyframe(&frame);
  } else {
    ok = Relocalize(&frame);
    if (ok) last_reloc_frame_index_ = frame.index;
  }
  int inliers = 0;
  if (ok) {
    inliers = TrackLocalMap(&frame);
    const bool recently_relocalized = frame.index - last_reloc_frame_index_ < shared_->options.keyframe.max_frames;
    const int needed = recently_relocalized ? shared_->options.min_inliers_after_reloc
                                            : shared_->options.min_inliers_local_map;
    ok = inliers >= needed;
  }
  if (ok) {
    // A frame the motion model could not place right after one it could (a sudden turn) is
    // placed from the last pose by the reference keyframe's points: with few matches that
    // pose can settle on a wrong translation that the local map then confirms (gen-2043: 124
    // local-map inliers at a pose 1.3 m off, made a keyframe 'urgently' that the server kept).
    // Such a weak pose makes no keyframe, and the velocity after it is measured across it,
    // from the frame before. A second fallback in a row is trusted: the motion model is not
    // coming back.
    // Likewise a frame whose inliers fell to a fraction of the last frame's in one step (a
    // blurred or badly exposed frame: gen-2043 agent 1 frame 227, 333 -> 121 inliers at a
    // pose 1.7 deg off): such a drop is also what makes a keyframe 'urgent', so without the
    // rule the one bad frame became a keyframe. A drop that persists is trusted on the next
    // frame, which compares with this one.
    const bool lone_fallback = shared_->options.weak_lone_fallback_poses && !by_motion_model && last_by_motion_model_;
    const bool inlier_drop = last_inliers_ > 0 && inliers < shared_->options.weak_inlier_drop_ratio * last_inliers_;
    const bool weak_pose = state_ == TrackingState::kTracking && (lone_fallback || inlier_drop);
    last_by_motion_model_ = by_motion_model;
    last_inliers_ = inliers;
    weak_poses_ += weak_pose;
    relocalizations_ += state_ == TrackingState::kLost;
    state_ = TrackingState::kTracking;
    lost_frames_ = 0;
    if (last_frame_) {
      const MotionBase last{last_frame_->world_from_cam, last_frame_->stamp_ns};
      const MotionBase& from = !weak_pose && before_weak_ ? *before_weak_ : last;
      velocity_ = frame.cam_from_world() * from.world_from_cam;
      velocity_dt_ns_ = frame.stamp_ns - from.stamp_ns;
      if (weak_pose) {
        before_weak_ = last;
      } else {
        before_weak_.reset();
      }
    }
    result.world_from_cam = frame.world_from_cam;
    result.inliers = inliers;
    if (const KeyframeReason why = weak_pose ? KeyframeReason::kNone : NeedNewKeyframe(frame, inliers);
        why != KeyframeReason::kNone) {
      ++keyframe_reasons_[static_cast<int>(why)];
      CreateKeyframe(frame);
      reference_inliers_ = inliers;
      result.new_keyframe = true;
    }
    frame.DiscardOutliers();
    last_frame_ = std::move(frame);
  } else if (map_->num_keyframes() <= static_cast<size_t>(shared_->options.reset_if_lost_below_keyframes)) {
    // Lost right after initialization: the initial map was probably wrong (ORB-SLAM
    // resets here too). Start over instead of relocalizing against it.
    ResetToInitialization();
    ++resets_;
  } else {
    state_ = TrackingState::kLost;
    velocity_.reset();
    last_inliers_ = 0;
    if (++lost_frames_ > shared_->options.lost_frames_before_new_segment) {
      StartNewSegment();
      result.new_segment = true;
    }
  }
  result.state = state_;
  result.segment = map_ ? map_->id() : MapId::Invalid();
  return result;
}

void Tracker::OnInitialized(const InitializationResult& init) {
  map_ = init.map;
  state_ = TrackingState::kTracking;
  reference_kf_ = init.kf2;
  reference_tracked_ = init.num_points;
  reference_inliers_ = 0;  // the initial pair's points: no tracked frame yet
  velocity_.reset();
  lost_frames_ = 0;
  sink_(KeyframeJob{map_, init.kf1, {}, true});
  sink_(KeyframeJob{map_, init.kf2, {}, true});
}

void Tracker::StartNewSegment() {
  // Relocalization kept failing: keep flying on a new local map; the server can merge
  // the segments later through place recognition.
  ResetToInitialization();
  ++segments_started_;
}

void Tracker::ResetToInitialization() {
  state_ = TrackingState::kInitializing;
  initializer_.Reset();
  map_.reset();
  reference_kf_.reset();
  covisible_reference_.reset();
  reference_inliers_ = 0;
  last_frame_.reset();
  before_weak_.reset();
  last_by_motion_model_ = false;
  last_inliers_ = 0;
  velocity_.reset();
  lost_frames_ = 0;
}

int Tracker::OptimizeFramePose(VoFrame* f) {
  std::vector<opt::PointObservation> obs;
  std::vector<int> kp_index;
  for (size_t i = 0; i < f->size(); ++i) {
    if (!f->map_points[i]) continue;
    const Keypoint& kp = f->features->keypoints[i];
    obs.push_back({f->map_points[i]->position(), Eigen::Vector2d(kp.u, kp.v), shared_->pyramid->scale[kp.level]});
    kp_index.push_back(static_cast<int>(i));
  }
  if (obs.size() < 3) return 0;
  SE3 pose = f->world_from_cam;
  const opt::OptimizationSummary s = opt::OptimizePose(*shared_->camera, obs, &pose);
  if (!s.usable) return 0;
  f->world_from_cam = pose;
  for (size_t k = 0; k < kp_index.size(); ++k) f->outlier[kp_index[k]] = !s.inlier[k];
  return s.num_inliers;
}

SE3 Tracker::PredictedMotion(int64_t stamp_ns) const {
  // Constant velocity in time, not per frame: after dropped frames (a camera or driver
  // hiccup) the camera moved for the whole gap. The twist is scaled by the ratio of the
  // intervals, capped: beyond a few intervals the prediction is a guess either way.
  const int64_t dt = stamp_ns - last_frame_->stamp_ns;
  if (velocity_dt_ns_ <= 0 || dt <= 0) return *velocity_;
  const double ratio = std::min(static_cast<double>(dt) / static_cast<double>(velocity_dt_ns_),
                                shared_->options.max_motion_extrapolation);
  if (std::abs(ratio - 1.0) < 0.25) return *velocity_;  // jitter of a regular stream
  return SE3::Exp(ratio * velocity_->Log());
}

bool Tracker::TrackWithMotionModel(VoFrame* f) {
  f->world_from_cam = (PredictedMotion(f->stamp_ns) * last_frame_->cam_from_world()).inverse();
  std::vector<std::shared_ptr<MapPoint>> points;
  for (size_t i = 0; i < last_frame_->size(); ++i) {
    if (last_frame_->map_points[i] && !last_frame_->map_points[i]->bad()) points.push_back(last_frame_->map_points[i]);
  }
  const CameraModel& cam = *shared_->camera;
  const double r = shared_->options.projection_radius_px;
  int n = SearchMapPointsByProjection(f, points, cam, *shared_->pyramid, r, false, 0.0);
  if (n < shared_->options.min_matches_motion_model) {
    std::fill(f->map_points.begin(), f->map_points.end(), nullptr);
    n = SearchMapPointsByProjection(f, points, cam, *shared_->pyramid, 2 * r, false, 0.0);
  }
  if (n < shared_->options.min_matches_motion_model) return false;
  const int inliers = OptimizeFramePoseRobustly(f);
  return inliers >= shared_->options.min_inliers_frame;
}

bool Tracker::TrackReferenceKeyframe(VoFrame* f) {
  if (!reference_kf_ || !last_frame_) return false;
  // No motion prior: start from the last pose and search the reference keyframe's
  // points in a wide window (a bag-of-words search once the vocabulary is wired in).
  f->world_from_cam = last_frame_->world_from_cam;
  std::fill(f->map_points.begin(), f->map_points.end(), nullptr);
  std::vector<std::shared_ptr<MapPoint>> points;
  for (const MapPointId id : reference_kf_->map_points()) {
    if (!id.valid()) continue;
    if (const auto mp = map_->map_point(id)) points.push_back(mp);
  }
  const int n = SearchMapPointsByProjection(f, points, *shared_->camera, *shared_->pyramid,
                                            4 * shared_->options.projection_radius_px, false, 0.0);
  if (n < shared_->options.min_matches_motion_model) return false;
  const int inliers = OptimizeFramePoseRobustly(f);
  return inliers >= shared_->options.min_inliers_frame;
}

bool Tracker::Relocalize(VoFrame* f) {
  if (!map_) return false;
  // Without a vocabulary: appearance matching against every point of the local map.
  if (!shared_->relocalization) return RelocalizeAgainst(f, map_->map_points());
  // With one: only the points around the keyframes that look like this frame (ORB-SLAM).
  const auto candidates = shared_->relocalization->Candidates(f->features->descriptors, *map_,
                                                              shared_->options.reloc_max_candidates);
  for (const auto& kf : candidates) {
    if (RelocalizeAgainst(f, PointsAround(*kf))) return true;
  }
  return false;
}

std::vector<std::shared_ptr<MapPoint>> Tracker::PointsAround(const KeyFrame& kf) const {
  std::vector<KeyframeId> kfs = kf.BestCovisible(shared_->options.reloc_covisible_keyframes);
  kfs.push_back(kf.id());
  std::unordered_set<MapPointId> seen;
  std::vector<std::shared_ptr<MapPoint>> points;
  for (const KeyframeId id : kfs) {
    const auto k = map_->keyframe(id);
    if (!k || k->bad()) continue;
    for (const MapPointId mp_id : k->map_points()) {
      if (!mp_id.valid() || !seen.insert(mp_id).second) continue;
      if (auto mp = map_->map_point(mp_id); mp && !mp->bad()) points.push_back(std::move(mp));
    }
  }
  return points;
}

bool Tracker::RelocalizeAgainst(VoFrame* f, const std::vector<std::shared_ptr<MapPoint>>& points) {
  const auto matches = MatchFrameToPoints(*f, points);
  if (static_cast<int>(matches.size()) < shared_->options.reloc_min_matches) return false;
  std::fill(f->map_points.begin(), f->map_points.end(), nullptr);
  std::fill(f->outlier.begin(), f->outlier.end(), false);
  for (const auto& [kp, mp] : matches) f->map_points[kp] = mp;
  return RansacFramePose(f) >= shared_->options.min_inliers_frame;
}

int Tracker::OptimizeFramePoseRobustly(VoFrame* f) {
  // The pose-only optimization starts at the predicted pose and trusts it: far off (a gap
  // longer than the motion model covers, a turn during it) it settles on a handful of
  // inliers among a majority of wrong matches. RANSAC needs no start, so it gets the
  // matches a second chance (a 16-frame gap on hall3 went from 9 to 150+ inliers).
  const std::vector<std::shared_ptr<MapPoint>> matches = f->map_points;
  int inliers = OptimizeFramePose(f);
  if (inliers < shared_->options.min_inliers_frame) {
    f->map_points = matches;
    std::fill(f->outlier.begin(), f->outlier.end(), false);
    inliers = RansacFramePose(f);
  }
  f->DiscardOutliers();
  return inliers;
}

int Tracker::RansacFramePose(VoFrame* f) {
  // P3P in RANSAC over the frame's matches, then the pose-only optimization on its inliers.
  std::vector<Eigen::Vector3d> bearings, world;
  std::vector<size_t> kp_index;
  for (size_t i = 0; i < f->size(); ++i) {
    if (!f->map_points[i]) continue;
    bearings.push_back(f->bearings[i]);
    world.push_back(f->map_points[i]->position());
    kp_index.push_back(i);
  }
  if (static_cast<int>(kp_index.size()) < shared_->options.reloc_min_matches) return 0;
  solvers::AbsolutePoseOptions o;
  o.ransac.focal_px = shared_->camera->intrinsics().fx;
  o.ransac.threshold_px = 4.0;
  o.ransac.max_iterations = 300;
  o.min_inliers = shared_->options.reloc_min_matches / 2;
  const auto pose = solvers::EstimateAbsolutePose(bearings, world, o);
  if (!pose.ok()) return 0;
  f->world_from_cam = pose.world_from_cam;
  for (size_t k = 0; k < kp_index.size(); ++k) {
    if (!pose.inliers[k]) f->map_points[kp_index[k]] = nullptr;
  }
  const int inliers = OptimizeFramePose(f);
  f->DiscardOutliers();
  return inliers;
}

std::vector<std::shared_ptr<KeyFrame>> Tracker::LocalKeyframes(const VoFrame& f) const {
  // Keyframes that see the frame's matched points, strongest first, plus their best
  // covisible neighbours (ORB-SLAM's local map), capped.
  std::unordered_map<KeyframeId, int> counts;
  for (size_t i = 0; i < f.size(); ++i) {
    if (!f.map_points[i] || f.outlier[i]) continue;
    for (const auto& [kf, idx] : f.map_points[i]->observations()) ++counts[kf];
  }
  std::vector<std::pair<int, KeyframeId>> ranked;
  for (const auto& [kf, n] : counts) ranked.emplace_back(n, kf);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  const size_t cap = static_cast<size_t>(shared_->options.local_map_max_keyframes);
  std::vector<std::shared_ptr<KeyFrame>> out;
  std::unordered_set<KeyframeId> taken;
  auto take = [&](KeyframeId id) {
    if (out.size() >= cap || taken.count(id)) return;
    if (const auto kf = map_->keyframe(id); kf && !kf->bad()) {
      taken.insert(id);
      out.push_back(kf);
    }
  };
  for (const auto& [n, id] : ranked) take(id);
  if (out.empty() && reference_kf_) take(reference_kf_->id());
  const size_t direct = out.size();
  // The server's neighbourhood (other agents' keyframes near ours) before our second ring.
  for (const KeyframeId id : shared_->neighbourhood.Get()) take(id);
  for (size_t k = 0; k < direct && out.size() < cap; ++k) {
    for (const KeyframeId n : out[k]->BestCovisible(10)) take(n);
  }
  return out;
}

int Tracker::TrackLocalMap(VoFrame* f) {
  const auto local_kfs = LocalKeyframes(*f);
  covisible_reference_ = local_kfs.empty() ? nullptr : local_kfs.front();
  std::unordered_set<MapPointId> already;
  for (size_t i = 0; i < f->size(); ++i) {
    if (f->map_points[i]) already.insert(f->map_points[i]->id());
  }
  std::vector<MapPointId> ids;  // ~10^4 per frame: looked up under one lock, not one each
  for (const auto& kf : local_kfs) {
    for (const MapPointId id : kf->map_points()) {
      if (id.valid() && already.insert(id).second) ids.push_back(id);
    }
  }
  std::vector<std::shared_ptr<MapPoint>> points;
  for (auto& mp : map_->map_points(ids)) {
    if (mp && !mp->bad()) points.push_back(std::move(mp));
  }
  SearchMapPointsByProjection(f, points, *shared_->camera, *shared_->pyramid, shared_->options.local_map_radius_px, true,
                              shared_->options.min_view_cos);
  const int inliers = OptimizeFramePose(f);
  for (size_t i = 0; i < f->size(); ++i) {
    if (f->map_points[i] && !f->outlier[i]) f->map_points[i]->IncreaseFound();
  }
  return inliers;
}

double Tracker::ImageCoverage(const VoFrame& f) const {
  // Coarse grid (8 x 6 cells): share of the cells holding a keypoint that also hold a
  // tracked point. Cells without any keypoint (sky, blank wall) do not count against it.
  constexpr int kCols = 8, kRows = 6;
  const double cw = static_cast<double>(shared_->camera->width()) / kCols;
  const double ch = static_cast<double>(shared_->camera->height()) / kRows;
  std::array<uint8_t, kCols * kRows> cell{};  // bit 0: keypoint, bit 1: tracked point
  for (size_t i = 0; i < f.size(); ++i) {
    const Keypoint& kp = f.features->keypoints[i];
    const int cx = std::clamp(static_cast<int>(kp.u / cw), 0, kCols - 1);
    const int cy = std::clamp(static_cast<int>(kp.v / ch), 0, kRows - 1);
    cell[cy * kCols + cx] |= (f.map_points[i] && !f.outlier[i]) ? 3 : 1;
  }
  int with_keypoint = 0, with_tracked = 0;
  for (const uint8_t c : cell) {
    with_keypoint += (c & 1) != 0;
    with_tracked += (c & 2) != 0;
  }
  return with_keypoint > 0 ? static_cast<double>(with_tracked) / with_keypoint : 0.0;
}

double Tracker::MedianDepth(const VoFrame& f) const {
  // From the frame, not map/MedianSceneDepth(map, kf): the new keyframe's points are linked
  // only when mapping inserts it, later.
  std::vector<double> depths;
  const SE3 cam_from_world = f.cam_from_world();
  for (size_t i = 0; i < f.size(); ++i) {
    if (!f.map_points[i] || f.outlier[i]) continue;
    const double z = (cam_from_world * f.map_points[i]->position()).z();
    if (z > 0) depths.push_back(z);
  }
  if (depths.empty()) return 0.0;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  return depths[depths.size() / 2];
}

double Tracker::BaselineOverDepth(const VoFrame& f) const {
  if (!reference_kf_ || reference_median_depth_ <= 0) return 0.0;
  const double baseline = (f.world_from_cam.translation() - reference_kf_->world_from_cam().translation()).norm();
  return baseline / reference_median_depth_;
}

KeyframeReason Tracker::NeedNewKeyframe(const VoFrame& f, int inliers) const {
  // ORB-SLAM's measure: all tracked points against the reference keyframe's points seen by
  // enough keyframes (2 while the map has two keyframes, else 3); until mapping processed
  // the reference, the count at creation. A measure of the overlap with the reference alone
  // (its points tracked / its best overlap since) was tried: it made 2-3x fewer keyframes
  // but doubled hall3's ATE (docs/vo.md, keyframe economy). The reference is our last
  // keyframe by default; ORB-SLAM's per-frame most covisible one (kf_reference) lost an agent
  // on the tuning scenes, so a stale count is caught by the inlier-drop criterion instead
  // (docs/vo.md, "Keyframes in a shared map").
  const int min_obs = map_->num_keyframes() <= 2 ? 2 : 3;
  auto well_seen = [&](const std::shared_ptr<KeyFrame>& kf) {
    int n = 0;
    for (const MapPointId id : kf->map_points()) {
      if (!id.valid()) continue;
      const auto mp = map_->map_point(id);
      n += mp && mp->num_observations() >= min_obs;
    }
    return n;
  };
  const KeyframeReference mode = shared_->options.kf_reference;
  int ref_points = reference_tracked_;
  if (mode != KeyframeReference::kMostCovisible && reference_kf_ && map_->keyframe(reference_kf_->id())) {
    ref_points = well_seen(reference_kf_);
  }
  if (mode != KeyframeReference::kLast && covisible_reference_ && map_->keyframe(covisible_reference_->id())) {
    const int n = well_seen(covisible_reference_);
    ref_points = mode == KeyframeReference::kMostCovisible ? n : std::max(ref_points, n);
  }
  KeyframeDecisionInput in;
  in.frames_since_kf = f.index - last_kf_frame_index_;
  in.seconds_since_kf = 1e-9 * static_cast<double>(f.stamp_ns - last_kf_stamp_ns_);
  in.inliers = inliers;
  in.reference_points = ref_points;
  in.reference_inliers = reference_inliers_;
  if (reference_coverage_ > 0) in.coverage = ImageCoverage(f);
  in.reference_coverage = reference_coverage_;
  if (reference_median_depth_ > 0) in.baseline_over_depth = BaselineOverDepth(f);
  if (shared_->options.keyframe.turn_fov_share > 0 && reference_kf_ && horizontal_fov_rad_ > 0) {
    const Eigen::AngleAxisd turn(reference_kf_->world_from_cam().rotation().inverse() * f.world_from_cam.rotation());
    in.turn_fov_share = turn.angle() / horizontal_fov_rad_;
  }
  in.mapper_idle = mapper_idle_();
  return DecideKeyframe(shared_->options.keyframe, in);
}

void Tracker::CreateKeyframe(const VoFrame& f) {
  auto kf = std::make_shared<KeyFrame>(shared_->kf_ids.Next(), f.stamp_ns, shared_->camera, f.features,
                                       shared_->pyramid, f.world_from_cam);
  KeyframeJob job{map_, kf, f.map_points, false};
  for (size_t i = 0; i < f.size(); ++i) {
    if (f.outlier[i]) job.matches[i] = nullptr;
  }
  reference_kf_ = kf;
  reference_tracked_ = f.NumMatched();
  RememberKeyframeFrame(f);
  sink_(std::move(job));
}

void Tracker::RememberKeyframeFrame(const VoFrame& f) {
  // Coverage and depth only when a criterion uses them (they are measured on every frame).
  const KeyframeDecisionOptions& o = shared_->options.keyframe;
  reference_coverage_ = o.coverage_ratio > 0 ? ImageCoverage(f) : 0.0;
  reference_median_depth_ = o.baseline_depth_ratio > 0 ? MedianDepth(f) : 0.0;
  last_kf_frame_index_ = f.index;
  last_kf_stamp_ns_ = f.stamp_ns;
}

}  // namespace ccm
