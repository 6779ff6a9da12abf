#include "slam_core/server/place_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "slam_core/map/drift_path.h"
#include "slam_core/place_recognition/map_adapter.h"

namespace ccm {

struct PlaceMatcher::QuerySnapshot {
  KeyframeId id;
  MapId map;
  VerificationView view;
  BowVector bow;
  SE3 world_from_cam;
  std::vector<KeyframeId> covisible;
  double depth = 1.0;
  size_t map_keyframes = 0;
};

namespace {

double MedianFiniteDepth(const VerificationView& v) {
  std::vector<double> d;
  for (const auto& p : v.points_cam) {
    if (p.allFinite() && p.z() > 0) d.push_back(p.z());
  }
  if (d.empty()) return 1.0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

double AngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a.conjugate() * b).angle() * 180.0 / M_PI;
}

// vocabulary_levels_up = -1 (automatic): depth 2 of the loaded vocabulary.
PlaceMatchingOptions Resolved(PlaceMatchingOptions o, const Vocabulary& vocabulary) {
  if (o.vocabulary_levels_up < 0) o.vocabulary_levels_up = std::max(0, vocabulary.levels() - 2);
  return o;
}

}  // namespace

PlaceMatcher::PlaceMatcher(std::shared_ptr<const Vocabulary> vocabulary, const PlaceMatchingOptions& options,
                           MapStack* stack)
    : vocabulary_(std::move(vocabulary)),
      options_(Resolved(options, *vocabulary_)),
      stack_(stack),
      database_(vocabulary_->num_words()) {}

std::optional<PlaceDetection> PlaceMatcher::Process(KeyframeId kf_id) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto smap = stack_->MapHolding(kf_id);
  if (!smap) return std::nullopt;
  QuerySnapshot q;
  {
    std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
    const auto kf = smap->map().keyframe(kf_id);
    if (smap->retired() || !kf) return std::nullopt;  // fused meanwhile / skipped: nothing to query
    q.id = kf_id;
    q.map = smap->id();
    q.view = MakeVerificationView(*kf, smap->map(), *vocabulary_, options_.vocabulary_levels_up, &q.bow);
    q.world_from_cam = kf->world_from_cam();
    q.covisible = kf->BestCovisible(-1);
    q.map_keyframes = smap->map().num_keyframes();
  }
  q.depth = MedianFiniteDepth(q.view);
  KeepNodes(kf_id, q.view.feature_vector, q.view.features.size());
  database_.Add(kf_id, q.map, q.bow);
  Bump(&PlaceMatcherStats::queries);
  ++agent_queries_[kf_id.agent()];
  const int64_t since_loop = ++keyframes_since_loop_[q.map];

  // ORB-SLAM's bar: a candidate must look at least as similar as the least similar
  // covisible neighbour. Without neighbours there is no bar to compare with: skip.
  if (q.covisible.empty()) return std::nullopt;
  CandidateOptions copt = options_.candidates;
  copt.min_score = database_.MinScore(q.bow, q.covisible);
  const CovisibilityFn covis = [this](KeyframeId id, int n) -> std::vector<KeyframeId> {
    const auto m = stack_->MapHolding(id);
    const auto k = m ? m->map().keyframe(id) : nullptr;
    return k ? k->BestCovisible(n) : std::vector<KeyframeId>{};
  };
  std::optional<PlaceDetection> found;
  if (static_cast<int>(q.map_keyframes) >= options_.loop_min_map_keyframes &&
      since_loop >= options_.min_keyframes_between_loops) {
    QueryFilter f;
    f.only_maps = {q.map};
    f.exclude_keyframes = q.covisible;
    f.exclude_keyframes.push_back(q.id);
    auto cands = database_.DetectCandidates(q.bow, f, copt, covis);
    // Recent keyframes of the same agent are its own VO neighbourhood, not a loop.
    cands.erase(std::remove_if(cands.begin(), cands.end(),
                               [&](const PlaceCandidate& c) {
                                 const KeyframeId k = c.best.keyframe;
                                 return k.agent() == q.id.agent() &&
                                        k.counter() + 2 * static_cast<uint64_t>(options_.min_keyframes_between_loops) >
                                            q.id.counter();
                               }),
                cands.end());
    Bump(&PlaceMatcherStats::loop_candidates, static_cast<int64_t>(cands.size()));
    found = TryCandidates(q, cands, PlaceDetection::Kind::kLoop);
  }
  if (!found && stack_->num_maps() > 1) {
    QueryFilter f;
    f.exclude_maps = {q.map};
    copt.min_common_ratio = options_.fusion_min_common_ratio;
    const auto cands = database_.DetectCandidates(q.bow, f, copt, covis);
    Bump(&PlaceMatcherStats::match_candidates, static_cast<int64_t>(cands.size()));
    FusionQueryTrace trace;
    if (options_.fusion_trace) {
      trace.query = q.id;
      trace.min_score = copt.min_score;
      trace.scored = database_.Query(q.bow, f);
      for (const PlaceCandidate& c : cands) trace.candidates.push_back(c.best.keyframe);
      trace_ = &trace;
    }
    found = TryCandidates(q, cands, PlaceDetection::Kind::kFusion);
    if (trace_) options_.fusion_trace(trace);
    trace_ = nullptr;
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.last_query_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    stats_.total_query_ms += stats_.last_query_ms;
  }
  return found;
}

std::optional<PlaceMatcher::View> PlaceMatcher::Snapshot(KeyframeId id, bool window) const {
  const auto smap = stack_->MapHolding(id);
  if (!smap) return std::nullopt;
  std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  const auto kf = smap->map().keyframe(id);
  if (smap->retired() || !kf) return std::nullopt;
  View v;
  v.id = id;
  v.map = smap->id();
  std::vector<std::shared_ptr<KeyFrame>> neighbours;
  if (window) {
    for (const KeyframeId n : kf->BestCovisible(options_.candidate_window)) {
      if (auto k = smap->map().keyframe(n)) neighbours.push_back(std::move(k));
    }
  }
  v.view = MakeWindowView(*kf, neighbours, smap->map(), [this](const KeyFrame& k) { return NodesOf(k); },
                          &v.real_keypoints);
  v.world_from_cam = kf->world_from_cam();
  v.depth = MedianFiniteDepth(v.view);
  v.covisible = kf->BestCovisible(kConfirmNeighbours);
  return v;
}

std::optional<PlaceMatcher::Pending> PlaceMatcher::Verify(const View& q, const View& c, PlaceDetection::Kind kind) {
  const VerificationResult v = VerifyPlace(c.view, q.view, options_.verification);
  if (kind == PlaceDetection::Kind::kFusion) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.fusion_stopped_at[static_cast<int>(v.stage)];
  }
  if (trace_ && kind == PlaceDetection::Kind::kFusion) {
    trace_->verifications.push_back({q.id, c.id, v.stage, v.bow_matches, v.ransac_inliers, v.total_matches});
  }
  if (!v.accepted) return std::nullopt;
  Bump(&PlaceMatcherStats::verified);
  Pending p;
  p.detection.kind = kind;
  p.detection.query = q.id;
  p.detection.candidate = c.id;
  p.detection.query_map = q.map;
  p.detection.candidate_map = c.map;
  p.detection.query_from_candidate = v.query_from_candidate;
  // Matches of a window's extra features name no keypoint of the candidate: fusion and loop
  // closing merge points by keypoint, and find the rest by projection anyway.
  for (const FeatureMatch& m : v.matches) {
    if (static_cast<size_t>(m.index1) < c.real_keypoints) p.detection.matches.push_back(m);
  }
  p.detection.inliers = v.final_inliers;
  p.depth = q.depth;
  p.query_count = kind == PlaceDetection::Kind::kLoop ? agent_queries_[q.id.agent()] : stats().queries;
  if (kind == PlaceDetection::Kind::kFusion) {
    // Normalized to "lower map id <- higher map id", so that a detection made from either
    // map (by either agent) confirms the other.
    const Sim3 q_from_c = Sim3(q.world_from_cam) * v.query_from_candidate * Sim3(c.world_from_cam.inverse());
    if (q.map < c.map) {
      p.map_transform = q_from_c;
      p.probe = c.world_from_cam.translation();
    } else {
      p.map_transform = q_from_c.inverse();
      p.probe = q.world_from_cam.translation();
      p.depth = q.depth * p.map_transform.scale();
    }
  } else {
    const Sim3 corrected_q = Sim3(c.world_from_cam) * v.query_from_candidate.inverse();
    p.map_transform = corrected_q * Sim3(q.world_from_cam.inverse());
    p.probe = q.world_from_cam.translation();
    // VO does not drift by tens of degrees in rotation: an aliased view.
    if (AngleDeg(Eigen::Quaterniond::Identity(), p.map_transform.rotation()) > options_.loop_max_correction_angle_deg) {
      return std::nullopt;
    }
    // Nor does it drift by a large share of the path flown since it saw the place: a
    // correction that big is an aliased view, e.g. the identical crate one row further,
    // which the neighbours confirm because the whole row repeats. Scale-free (both in map
    // units); a correction within the consistency tolerance of the scene depth always
    // passes (short paths). With another agent's keyframe the path runs through the
    // place where the two agents' keyframes already share points (DriftPath); two agents
    // without one have no bound. The depth test first: most corrections pass it and need
    // no walk along the path.
    const double moved = (corrected_q.translation() - q.world_from_cam.translation()).norm();
    if (moved > options_.consistency_max_position_ratio * q.depth) {
      const auto path = DriftPathBetween(c.id, q.id);
      if (path && moved > options_.loop_max_correction_path_ratio * *path) {
        Bump(&PlaceMatcherStats::implausible_loops);
        return std::nullopt;
      }
    }
  }
  return p;
}

std::optional<PlaceDetection> PlaceMatcher::TryCandidates(const QuerySnapshot& q,
                                                          const std::vector<PlaceCandidate>& candidates,
                                                          PlaceDetection::Kind kind) {
  View qv;
  qv.id = q.id;
  qv.map = q.map;
  qv.view = q.view;
  qv.world_from_cam = q.world_from_cam;
  qv.depth = q.depth;
  qv.real_keypoints = q.view.features.size();
  qv.covisible = std::vector<KeyframeId>(q.covisible.begin(),
                                         q.covisible.begin() + std::min<size_t>(q.covisible.size(), kConfirmNeighbours));
  for (const PlaceCandidate& cand : candidates) {
    // Windows for map matching only: other agents see a place from other heights and angles.
    // For loops (the same agent, the same camera path) a window brought no loop on the
    // tuning scenes and one false one (seed 1, agent 3).
    const auto cv = Snapshot(cand.best.keyframe, /*window=*/kind == PlaceDetection::Kind::kFusion);
    if (!cv || (kind == PlaceDetection::Kind::kLoop) != (cv->map == q.map)) continue;  // maps changed meanwhile
    const auto p = Verify(qv, *cv, kind);
    if (!p) continue;
    if (auto confirmed = ConfirmWithNeighbours(qv, *cv, *p)) return confirmed;
    return CheckConsistency(*p);
  }
  return std::nullopt;
}

std::optional<PlaceDetection> PlaceMatcher::ConfirmWithNeighbours(const View& q, const View& c, const Pending& first) {
  // A second view pair of the same place must imply the same map-level transform: the
  // query's covisible neighbours against the candidate and its neighbours (ORB-SLAM3 checks
  // a merge with the query's covisible keyframes the same way). Confirmed at once, so an
  // agent that makes few keyframes needs no second lucky query.
  std::vector<View> candidates{c};
  for (const KeyframeId id : c.covisible) {
    if (auto v = Snapshot(id); v && v->map == c.map) candidates.push_back(std::move(*v));
  }
  for (const KeyframeId nid : q.covisible) {
    const auto n = Snapshot(nid);
    if (!n || n->map != q.map) continue;
    for (const View& cc : candidates) {
      if (first.detection.kind == PlaceDetection::Kind::kLoop && (cc.id == n->id)) continue;
      const auto p = Verify(*n, cc, first.detection.kind);
      if (!p || !Agree(first, *p)) continue;
      PlaceDetection accepted = first.detection;
      accepted.confirmed_by = nid;
      Bump(first.detection.kind == PlaceDetection::Kind::kLoop ? &PlaceMatcherStats::accepted_loops
                                                               : &PlaceMatcherStats::accepted_fusions);
      return accepted;
    }
  }
  return std::nullopt;
}

std::optional<double> PlaceMatcher::DriftPathBetween(KeyframeId from, KeyframeId to) const {
  const auto smap = stack_->MapHolding(to);
  if (!smap) return std::nullopt;
  std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  return DriftPath(smap->map(), from, to, smap->map().options().covisibility_min_shared);
}

bool PlaceMatcher::Agree(const Pending& a, const Pending& b) const {
  if (AngleDeg(a.map_transform.rotation(), b.map_transform.rotation()) > options_.consistency_max_angle_deg) return false;
  if (std::abs(std::log(a.map_transform.scale() / b.map_transform.scale())) > options_.consistency_max_scale_diff) {
    return false;
  }
  const double d = (a.map_transform * b.probe - b.map_transform * b.probe).norm();
  return d <= options_.consistency_max_position_ratio * b.depth;
}

std::optional<PlaceDetection> PlaceMatcher::CheckConsistency(const Pending& fresh) {
  const PlaceDetection& d = fresh.detection;
  const bool loop = d.kind == PlaceDetection::Kind::kLoop;
  // Loops: the same agent's next keyframes must confirm. Fusions: any keyframe of either
  // map, within the window counted in queries of all agents.
  const auto key = loop ? std::make_tuple(static_cast<int>(d.kind), MapId::Make(d.query.agent(), 0), d.query_map)
                        : std::make_tuple(static_cast<int>(d.kind), std::min(d.query_map, d.candidate_map),
                                          std::max(d.query_map, d.candidate_map));
  const int64_t window = loop ? options_.consistency_window_keyframes
                              : options_.consistency_window_keyframes * std::max<int64_t>(1, agent_queries_.size());
  const auto it = pending_.find(key);
  if (it != pending_.end()) {
    const Pending& old = it->second;
    const bool in_window = fresh.query_count - old.query_count <= window && old.detection.query != d.query;
    if (in_window && Agree(old, fresh)) {
      PlaceDetection accepted = d;
      accepted.confirmed_by = old.detection.query;
      pending_.erase(it);
      Bump(loop ? &PlaceMatcherStats::accepted_loops : &PlaceMatcherStats::accepted_fusions);
      return accepted;
    }
    Bump(&PlaceMatcherStats::inconsistent);
  }
  pending_[key] = fresh;
  return std::nullopt;
}

void PlaceMatcher::AddToDatabase(const KeyFrame& kf, MapId map) {
  BowVector bow;
  FeatureVector features;
  vocabulary_->Transform(kf.features().descriptors, &bow, &features, options_.vocabulary_levels_up);
  KeepNodes(kf.id(), features, kf.features().size());
  database_.Add(kf.id(), map, bow);
}

void PlaceMatcher::KeepNodes(KeyframeId kf, const FeatureVector& features, size_t num_features) {
  std::vector<NodeId> nodes = NodesOfFeatures(features, num_features);
  std::lock_guard<std::mutex> lock(nodes_mutex_);
  nodes_[kf] = std::move(nodes);
}

std::vector<NodeId> PlaceMatcher::NodesOf(const KeyFrame& kf) const {
  {
    std::lock_guard<std::mutex> lock(nodes_mutex_);
    const auto it = nodes_.find(kf.id());
    if (it != nodes_.end() && it->second.size() == kf.features().size()) return it->second;
  }
  // Not queried yet (a neighbour that arrived after the candidate was queried): computed, and
  // kept only once the keyframe is queried itself.
  return VocabularyNodes(*vocabulary_, options_.vocabulary_levels_up)(kf);
}

void PlaceMatcher::OnMapsFused(MapId from, MapId into) {
  database_.ReassignMap(from, into);
  for (auto it = pending_.begin(); it != pending_.end();) {
    const PlaceDetection& d = it->second.detection;
    const bool stale = d.query_map == from || d.candidate_map == from || d.query_map == into || d.candidate_map == into;
    it = stale ? pending_.erase(it) : std::next(it);
  }
  keyframes_since_loop_[into] = 0;
}

void PlaceMatcher::OnLoopClosed(MapId map) {
  keyframes_since_loop_[map] = 0;
  for (auto it = pending_.begin(); it != pending_.end();) {
    const PlaceDetection& d = it->second.detection;
    it = d.query_map == map ? pending_.erase(it) : std::next(it);
  }
}

}  // namespace ccm
