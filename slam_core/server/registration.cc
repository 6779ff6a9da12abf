#include "slam_core/server/registration.h"

#include <algorithm>
#include <limits>
#include <optional>
#include <unordered_set>

#include "slam_core/map_ops/map_bundle_adjustment.h"
#include "slam_core/optimization/bundle_adjustment.h"

namespace ccm {
namespace {

// p_map = S * p_segment for the handler, from one keyframe seen in both frames.
Sim3 MapFromSegment(const SE3& map_from_cam, const SE3& segment_from_cam, double scale) {
  const Eigen::Quaterniond q = map_from_cam.rotation() * segment_from_cam.rotation().conjugate();
  const Eigen::Vector3d t = map_from_cam.translation() - scale * (q * segment_from_cam.translation());
  return Sim3(scale, q, t);
}

}  // namespace

SharedMapLock LockHandlerMap(MapStack* stack, AgentId agent, MapId segment, bool* created) {
  for (;;) {
    bool made = false;
    auto map = stack->MapFor(agent, segment, &made);
    if (created) *created = *created || made;
    if (!map) continue;  // fused away between lookup and now: resolve again
    std::shared_lock<WriterPreferringMutex> lock(map->structure_mutex());
    if (!map->retired()) return {std::move(map), std::move(lock)};
  }
}

AgentRegistration::AgentRegistration(AgentId agent, MapStack* stack, const RegistrationOptions& options)
    : agent_(agent), stack_(stack), options_(options) {}

size_t AgentRegistration::points_waiting() const { return num_waiting_; }

std::shared_ptr<const ScalePyramid> AgentRegistration::Pyramid(int levels, double factor) {
  auto& p = pyramids_[{levels, factor}];
  if (!p) p = std::make_shared<ScalePyramid>(ScalePyramid::Make(levels, factor));
  return p;
}

RegistrationReport AgentRegistration::Register(const AgentBatch& batch) {
  RegistrationReport report;
  std::vector<const KeyframeData*> kfs;
  for (const auto& kf : batch.keyframes) kfs.push_back(&kf);
  std::sort(kfs.begin(), kfs.end(), [](const auto* a, const auto* b) { return a->id < b->id; });
  for (const KeyframeData* kf : kfs) RegisterKeyframe(*kf, &report);
  for (const MapPointData& mp : batch.map_points) RegisterPoint(mp, &report);
  for (const KeyframePoseUpdate& u : batch.keyframe_updates) ApplyKeyframeUpdate(u, &report);
  for (const MapPointPositionUpdate& u : batch.map_point_updates) ApplyPointUpdate(u, batch.segment, &report);
  for (auto it = deferred_.begin(); it != deferred_.end();) {
    Deferred& d = it->second;
    if (2 * d.resolved >= d.pending || ++d.batches > kMaxDeferredBatches) {
      report.completed.push_back(it->first);
      it = deferred_.erase(it);
    } else {
      ++it;
    }
  }
  report.points_waiting = static_cast<int>(num_waiting_);
  return report;
}

void AgentRegistration::RegisterKeyframe(const KeyframeData& data, RegistrationReport* report) {
  bool created = false;
  SharedMapLock locked = LockHandlerMap(stack_, agent_, data.segment, &created);
  ServerMap* smap = locked.map.get();
  if (created) report->new_maps.push_back(smap->id());
  report->acked_keyframes.push_back(data.id);
  if (smap->Knows(data.id)) return;  // a resend of something we have
  const AgentHandler handler = *stack_->Handler(agent_, data.segment);
  if (data.anchor_only) {
    RegisterAnchor(data, handler.scale, smap, report);
    locked.lock.unlock();  // see below
    ReleaseWaitingPoints(data.id, report);
    return;
  }

  RegisteredKeyframe reg{data.id, smap->id(), RegisteredKeyframe::Placement::kFirstOfMap, false};
  SE3 world_from_cam;
  if (const auto pred = data.predecessor.valid() ? smap->PoseOf(data.predecessor) : std::nullopt) {
    world_from_cam = *pred * ScaledPose(data.pred_from_cam, handler.scale);
    reg.placement = RegisteredKeyframe::Placement::kPredecessor;
  } else if (const auto par = data.parent.valid() ? smap->PoseOf(data.parent) : std::nullopt) {
    world_from_cam = *par * ScaledPose(data.parent_from_cam, handler.scale);
    reg.placement = RegisteredKeyframe::Placement::kParent;
  } else if (handler.keyframes > 0) {
    world_from_cam = handler.map_from_segment.TransformPose(data.segment_from_cam);
    reg.placement = RegisteredKeyframe::Placement::kSegmentPose;
  } else {
    // The segment's first keyframe defines its map's frame: the map starts as the VO frame.
    world_from_cam = data.segment_from_cam;
  }
  auto kf = std::make_shared<KeyFrame>(data.id, data.stamp_ns, data.camera, data.features,
                                       Pyramid(data.pyramid_levels, data.pyramid_scale_factor), world_from_cam);
  Map& map = smap->map();
  map.AddKeyframe(kf);
  ServerKeyframeInfo info;
  info.segment = data.segment;
  info.predecessor = data.predecessor;
  info.parent = data.parent;
  info.pred_from_cam = data.pred_from_cam;
  info.parent_from_cam = data.parent_from_cam;
  info.segment_from_cam = data.segment_from_cam;
  smap->SetInfo(data.id, info);
  int pending = 0;
  for (const auto& [idx, mp_id] : data.point_links) {
    const MapPointId resolved = smap->Resolve(mp_id);
    if (map.map_point(resolved)) {
      map.AddObservation(data.id, idx, resolved);
    } else if (mp_id.agent() == agent_) {
      AddPendingLink(mp_id, data.id, idx);
      ++pending;
    }
  }
  int inliers = 0;
  bool kept_on_track = false, implausible = false;
  const KeyframeId continuity = reg.placement == RegisteredKeyframe::Placement::kPredecessor ? data.predecessor
                                : reg.placement == RegisteredKeyframe::Placement::kParent    ? data.parent
                                                                                              : KeyframeId();
  if (data.points_incomplete && pending > 0) {
    reg.deferred = true;
    deferred_[data.id].pending = pending;
    // Most of its own points are still on their way: the few links it has (after an
    // outage, often only points of an earlier pass that the server holds elsewhere) would
    // pull it off the agent's track, and every later keyframe hangs on it. Its relative
    // pose places it; links that disagree with that are dropped (loop closing joins the
    // places), and the late points join it when they arrive.
    DropLinksAgainstPose(&map, *kf);
  } else {
    reg.refined = RefinePose(smap, kf.get(), continuity, &inliers, &kept_on_track, &implausible);
  }
  report->kept_on_track += kept_on_track;
  report->implausible_refinements += implausible;
  if (reg.refined && reg.placement == RegisteredKeyframe::Placement::kPredecessor) {
    UpdateScale(handler, data, smap, *kf);
  }
  const SE3 final_pose = kf->world_from_cam();
  stack_->EditHandler(agent_, data.segment, [&](AgentHandler* h) {
    if (!h->last_keyframe.valid() || h->last_keyframe < data.id) h->last_keyframe = data.id;
    ++h->keyframes;
    h->map_from_segment = MapFromSegment(final_pose, data.segment_from_cam, h->scale);
  });
  report->keyframes.push_back(reg);
  // RegisterPoint takes the map's shared lock itself. Taking it twice on one thread
  // deadlocks as soon as a writer (fusion, loop closure, global BA) queues in between: the
  // mutex prefers writers, so the second shared lock waits for the writer, which waits for
  // the first. (Seen in the demo once agents tracked shared points.)
  locked.lock.unlock();
  ReleaseWaitingPoints(data.id, report);
}

void AgentRegistration::RegisterAnchor(const KeyframeData& data, double scale, ServerMap* smap,
                                       RegistrationReport* report) {
  // Placed relative to the keyframe it duplicates (the agent's VO relative pose between two
  // keyframes a few centimetres apart is as good as it gets), else to its predecessor.
  KeyframeId via = data.parent;
  SE3 via_from_cam = data.parent_from_cam;
  std::optional<SE3> world_from_via = smap->PoseOf(via);
  if (!world_from_via && data.predecessor.valid()) {
    via = data.predecessor;
    via_from_cam = data.pred_from_cam;
    world_from_via = smap->PoseOf(via);
  }
  if (!world_from_via) {
    ++report->anchors_dropped;  // nothing it could hang on (both were lost): acked, not kept
    return;
  }
  // Anchor it on a keyframe in the map, so chains of anchors stay short.
  const KeyframeId base = smap->AnchorRoot(via);
  const auto base_kf = smap->map().keyframe(base);
  if (!base_kf) {
    ++report->anchors_dropped;
    return;
  }
  const SE3 world_from_cam = *world_from_via * ScaledPose(via_from_cam, scale);
  smap->AddAnchor(data.id, {base, base_kf->cam_from_world() * world_from_cam, data.stamp_ns, data.segment});
  ++report->anchors_registered;
}

void AgentRegistration::DropLinksAgainstPose(Map* map, const KeyFrame& kf) {
  std::vector<MapPointId> refs;
  const std::vector<opt::PointObservation> obs = LinkedPointObservations(*map, kf, &refs);
  std::vector<bool> inlier(obs.size(), false);
  opt::ClassifyObservations(kf.camera(), obs, kf.cam_from_world(), opt::kChi2Mono2Dof, &inlier);
  for (size_t i = 0; i < refs.size(); ++i) {
    if (!inlier[i]) map->EraseObservation(kf.id(), refs[i]);
  }
}

bool AgentRegistration::RefinePose(ServerMap* smap, KeyFrame* kf, KeyframeId continuity, int* inliers,
                                   bool* kept_on_track, bool* implausible) {
  Map& map = smap->map();
  std::vector<MapPointId> refs;
  const std::vector<opt::PointObservation> obs = LinkedPointObservations(map, *kf, &refs);
  *inliers = 0;
  if (static_cast<int>(obs.size()) < options_.refine_min_inliers) return false;
  const SE3 placed = kf->world_from_cam();
  SE3 pose = placed;
  opt::OptimizationSummary s = opt::OptimizePose(kf->camera(), obs, &pose);
  // Most links must agree: a placement far off (or wrong links) would converge to
  // something wrong, and its outliers must not be erased then.
  const auto most_agree = [&](const opt::OptimizationSummary& r, size_t links) {
    return r.usable && r.num_inliers >= options_.refine_min_inliers && 2 * r.num_inliers >= static_cast<int>(links);
  };
  const auto before = continuity.valid() ? map.keyframe(continuity) : nullptr;
  // The links to points the keyframe it hangs on sees as well carry the agent's track.
  std::optional<SE3> continued;
  const auto refine_on_track = [&]() {
    if (continued || !before) return;
    const auto seen_before = before->map_points();
    const std::unordered_set<MapPointId> continuing(seen_before.begin(), seen_before.end());
    std::vector<opt::PointObservation> tracked;
    for (size_t i = 0; i < refs.size(); ++i) {
      if (continuing.count(refs[i])) tracked.push_back(obs[i]);
    }
    SE3 p = placed;
    if (most_agree(opt::OptimizePose(kf->camera(), tracked, &p), tracked.size())) continued = p;
  };
  // How far the map may pull the keyframe from where the agent's relative pose put it on
  // the links' word alone: the agent's VO drifts by a small share of a step from one
  // keyframe to the next, and the keyframe it hangs on is in the map's frame already. A
  // pull beyond that stands only if the track agrees (an agent whose VO drifts fast, or a
  // map that a loop or fusion moved under it) or a clear majority of the links agrees with
  // it (refine_far_pull_min_share); otherwise it is a pose the links fit by chance
  // (seen: 20 of 38 links pulling a keyframe back 2 m along a 1 m step after a loop had moved
  // the points it came back to, with every later keyframe of the agent hung on it). Without
  // a keyframe to hang on, the refinement is the placement.
  // The scene-depth floor (a median over the keyframe's points) only where the step bound
  // alone would refuse: most pulls are well inside it.
  const double step_pull =
      before ? options_.refine_max_step_share * (placed.translation() - before->world_from_cam().translation()).norm()
             : std::numeric_limits<double>::infinity();
  std::optional<double> depth_pull;
  const auto within = [&](const SE3& a, const SE3& b) {
    const double d = (a.translation() - b.translation()).norm();
    if (d <= step_pull) return true;
    if (!depth_pull) depth_pull = options_.refine_min_pull_depth_ratio * MedianSceneDepth(map, *kf);
    return d <= *depth_pull;
  };
  bool ok = most_agree(s, obs.size());
  if (ok && !within(pose, placed) &&
      s.num_inliers < options_.refine_far_pull_min_share * static_cast<double>(obs.size())) {
    refine_on_track();
    if (!continued || !within(*continued, pose)) ok = false, *implausible = true;
  }
  if (!ok && before) {
    // Most links disagree with every pose (or pull it where the track does not go). Seen
    // when an agent is back where it was and tracks old points that the server holds
    // elsewhere (drift the server has not closed as a loop yet, or points it fused
    // differently): left in the map, those links tear it between this keyframe and its
    // predecessor, local BA bends the agent's whole part around the tear, and the keyframe
    // looks covisible with the old ones, which hides the loop from place recognition. The
    // points the predecessor sees as well carry the track: if they agree on a pose, it is
    // the keyframe's, and the links that disagree with it are dropped (loop closing joins
    // the two places properly).
    refine_on_track();
    if (continued) {
      pose = *continued;
      s.inlier.assign(obs.size(), false);
      s.num_inliers = opt::ClassifyObservations(kf->camera(), obs, pose.inverse(), opt::kChi2Mono2Dof, &s.inlier);
      ok = *kept_on_track = true;
    }
  }
  if (!ok) return false;
  kf->SetWorldFromCam(pose);
  *inliers = s.num_inliers;
  // Outlier links would pull later optimizations: drop them (the agent's link was wrong or
  // the point was fused differently on the server).
  for (size_t i = 0; i < refs.size(); ++i) {
    if (!s.inlier[i]) map.EraseObservation(kf->id(), refs[i]);
  }
  return true;
}

void AgentRegistration::UpdateScale(const AgentHandler& handler, const KeyframeData& data, ServerMap* smap,
                                    const KeyFrame& kf) {
  const auto pred = smap->PoseOf(data.predecessor);
  const double received = data.pred_from_cam.translation().norm();
  const double depth = MedianSceneDepth(smap->map(), kf);
  if (!pred || depth <= 0.0 || received * handler.scale < options_.scale_min_baseline_depth_ratio * depth) return;
  const double after = (pred->inverse() * kf.world_from_cam()).translation().norm();
  const double sample = after / received;
  if (sample > handler.scale * options_.scale_max_step || sample < handler.scale / options_.scale_max_step) return;
  stack_->EditHandler(agent_, data.segment, [&](AgentHandler* h) {
    h->scale += options_.scale_kappa * (sample - h->scale);
  });
}

void AgentRegistration::RegisterPoint(const MapPointData& data, RegistrationReport* report) {
  SharedMapLock locked = LockHandlerMap(stack_, agent_, data.segment);
  ServerMap* smap = locked.map.get();
  Map& map = smap->map();
  const MapPointId resolved = smap->Resolve(data.id);
  if (map.map_point(resolved) || resolved != data.id) {
    report->acked_points.push_back(data.id);  // known (a resend) or merged into another point
    return;
  }
  const auto ref_pose = smap->PoseOf(data.reference_kf);
  if (!ref_pose) {
    if (static_cast<int>(num_waiting_) >= options_.max_pending_points) {
      ++report->points_dropped;
      return;
    }
    waiting_[data.reference_kf].push_back(data);
    ++num_waiting_;
    return;
  }
  report->acked_points.push_back(data.id);
  const double scale = stack_->Handler(agent_, data.segment)->scale;
  const Eigen::Vector3d p_w = *ref_pose * (scale * data.position_ref);
  KeyframeId ref = data.reference_kf;
  auto mp = std::make_shared<MapPoint>(data.id, p_w, ref, data.descriptor);
  map.AddMapPoint(mp);
  for (const auto& [kf_id, idx] : data.observations) map.AddObservation(kf_id, idx, data.id);
  if (const auto it = pending_links_.find(data.id); it != pending_links_.end()) {
    for (const auto& [kf_id, idx] : it->second) {
      map.AddObservation(kf_id, idx, data.id);
      if (const auto d = deferred_.find(kf_id); d != deferred_.end()) ++d->second.resolved;
    }
    pending_links_.erase(it);
  }
  if (mp->num_observations() == 0) {
    map.EraseMapPoint(data.id);  // every observer was skipped or removed
    ++report->points_dropped;
    return;
  }
  if (!map.keyframe(ref)) mp->SetReferenceKf(mp->observations().front().first);
  map.UpdateMapPointAppearance(data.id);
  ++report->points_registered;
}

void AgentRegistration::AddPendingLink(MapPointId mp, KeyframeId kf, int keypoint) {
  auto& links = pending_links_[mp];
  if (links.empty()) pending_order_.push_back(mp);
  links.emplace_back(kf, keypoint);
  // pending_order_ also holds ids that resolved since (cheap to skip); the cap bounds both.
  while (pending_order_.size() > static_cast<size_t>(options_.max_pending_links)) {
    pending_links_.erase(pending_order_.front());
    pending_order_.pop_front();
  }
}

void AgentRegistration::ReleaseWaitingPoints(KeyframeId kf, RegistrationReport* report) {
  const auto it = waiting_.find(kf);
  if (it == waiting_.end()) return;
  std::vector<MapPointData> points = std::move(it->second);
  waiting_.erase(it);
  num_waiting_ -= points.size();
  for (const MapPointData& mp : points) RegisterPoint(mp, report);
}

void AgentRegistration::ApplyKeyframeUpdate(const KeyframePoseUpdate& u, RegistrationReport* report) {
  SharedMapLock locked = LockHandlerMap(stack_, agent_, u.segment);
  ServerMap* smap = locked.map.get();
  const auto kf = smap->map().keyframe(u.id);
  const auto info = smap->Info(u.id);
  if (!kf || !info || info->settled) {
    ++report->updates_ignored;
    return;
  }
  const double scale = stack_->Handler(agent_, u.segment)->scale;
  std::optional<SE3> pose;
  if (const auto pred = u.predecessor.valid() ? smap->PoseOf(u.predecessor) : std::nullopt) {
    pose = *pred * ScaledPose(u.pred_from_cam, scale);
  } else if (const auto par = u.parent.valid() ? smap->PoseOf(u.parent) : std::nullopt) {
    pose = *par * ScaledPose(u.parent_from_cam, scale);
  }
  if (!pose) {
    ++report->updates_ignored;
    return;
  }
  kf->SetWorldFromCam(*pose);
  ServerKeyframeInfo updated = *info;
  updated.predecessor = u.predecessor;
  updated.pred_from_cam = u.pred_from_cam;
  updated.parent = u.parent;
  updated.parent_from_cam = u.parent_from_cam;
  smap->SetInfo(u.id, updated);
  ++report->keyframe_updates_applied;
}

void AgentRegistration::ApplyPointUpdate(const MapPointPositionUpdate& u, MapId segment, RegistrationReport* report) {
  SharedMapLock locked = LockHandlerMap(stack_, agent_, segment);
  ServerMap* smap = locked.map.get();
  const auto mp = smap->map().map_point(u.id);
  const auto info = smap->Info(u.reference_kf);
  const auto ref_pose = smap->PoseOf(u.reference_kf);
  if (!mp || !ref_pose || !info || info->settled) {
    ++report->updates_ignored;
    return;
  }
  const double scale = stack_->Handler(agent_, segment)->scale;
  mp->SetPosition(*ref_pose * (scale * u.position_ref));
  ++report->point_updates_applied;
}

}  // namespace ccm
