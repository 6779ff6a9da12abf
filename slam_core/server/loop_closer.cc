#include "slam_core/server/loop_closer.h"

#include <chrono>
#include <functional>
#include <set>
#include <unordered_set>

#include "slam_core/common/stopwatch.h"
#include "slam_core/map_ops/point_fusion.h"
#include "slam_core/server/map_correction.h"

namespace ccm {
namespace {

using Clock = std::chrono::steady_clock;

constexpr double kLoopFusionRadiusPx = 4.0;  // ORB-SLAM's SearchAndFuse radius for loops

std::vector<std::shared_ptr<MapPoint>> PointsAround(const Map& map, const std::shared_ptr<KeyFrame>& kf, int neighbours) {
  std::vector<std::shared_ptr<MapPoint>> out;
  std::unordered_set<MapPointId> seen;
  std::vector<std::shared_ptr<KeyFrame>> kfs{kf};
  for (const KeyframeId id : kf->BestCovisible(neighbours)) {
    if (const auto n = map.keyframe(id)) kfs.push_back(n);
  }
  for (const auto& k : kfs) {
    for (const auto& mp : PointsOf(map, *k)) {
      if (seen.insert(mp->id()).second) out.push_back(mp);
    }
  }
  return out;
}

// Fuses the verification's own matches: the candidate's point stands for the query's.
void FuseVerifiedMatches(Map* map, const KeyFrame& c, const KeyFrame& q, const std::vector<FeatureMatch>& matches,
                         PointFusionResult* r) {
  for (const FeatureMatch& m : matches) {
    const MapPointId cp = c.MapPointAt(m.index1);
    if (!cp.valid() || !map->map_point(cp)) continue;
    const MapPointId qp = q.MapPointAt(m.index2);
    if (qp == cp) continue;
    if (!qp.valid()) {
      r->linked += map->AddObservation(q.id(), m.index2, cp) ? 1 : 0;
    } else if (map->ReplaceMapPoint(qp, cp)) {
      ++r->fused;
      r->replaced.emplace_back(qp, cp);
    }
  }
}

// Each handler's lambda follows the scale change `scale_of` gives for its newest keyframe
// (or the keyframe its newest near-duplicate is anchored to).
void RescaleHandlers(MapStack* stack, const ServerMap& smap, const std::function<double(KeyframeId)>& scale_of) {
  for (const AgentHandler& h : stack->HandlersOfMap(smap.id())) {
    KeyframeId node = h.last_keyframe;
    if (!smap.map().keyframe(node)) {
      const auto anchor = smap.Anchor(node);
      node = anchor ? anchor->base : KeyframeId::Invalid();
    }
    if (!node.valid()) continue;
    const double s = scale_of(node);
    if (s != 1.0) stack->EditHandler(h.agent, h.segment, [s](AgentHandler* e) { e->scale *= s; });
  }
}

}  // namespace

LoopReport CloseLoop(MapStack* stack, const PlaceDetection& d, const ServerOptions& options) {
  const auto t0 = Clock::now();
  LoopReport r;
  r.map = d.query_map;
  r.query = d.query;
  r.candidate = d.candidate;
  const auto smap = stack->GetMap(d.query_map);
  if (!smap) {
    r.reason = "map no longer exists";
    return r;
  }
  std::unique_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  auto t_locked = Clock::now();
  Map& map = smap->map();
  const auto q = map.keyframe(d.query), c = map.keyframe(d.candidate);
  if (smap->retired() || !q || !c) {
    r.reason = "query or candidate left the map";
    return r;
  }
  EssentialGraphCorrection corr;
  for (const auto& kf : map.keyframes()) corr.before.emplace(kf->id(), kf->world_from_cam());
  const SE3 query_before = q->world_from_cam();
  const Sim3 corrected_q = Sim3(c->world_from_cam()) * d.query_from_candidate.inverse();

  // The query's neighbourhood moves rigidly with it (the candidate's side stays).
  std::set<KeyframeId> candidate_side{c->id()};
  for (const KeyframeId id : c->BestCovisible(-1)) candidate_side.insert(id);
  std::vector<std::shared_ptr<KeyFrame>> hood{q};
  for (const KeyframeId id : q->BestCovisible(-1)) {
    const auto n = map.keyframe(id);
    if (n && !candidate_side.count(id)) hood.push_back(n);
  }
  std::map<KeyframeId, std::set<KeyframeId>> links_before;
  std::unordered_map<MapPointId, KeyframeId> moved_by;
  for (const auto& n : hood) {
    const Sim3 s = corrected_q * Sim3(query_before.inverse() * n->world_from_cam());
    corr.corrected.emplace(n->id(), s);
    for (const auto& [m, w] : n->covisibility()) links_before[n->id()].insert(m);
  }
  for (const auto& n : hood) {
    const SE3 cam_from_world = n->cam_from_world();
    const Sim3& s = corr.corrected.at(n->id());
    for (const auto& mp : PointsOf(map, *n)) {
      if (!moved_by.emplace(mp->id(), n->id()).second) continue;
      mp->SetPosition(s * (cam_from_world * mp->position()));
    }
  }
  for (const auto& n : hood) n->SetWorldFromCam(opt::RigidPose(corr.corrected.at(n->id())));
  // Handlers and anchors of the neighbourhood take its scale now: keyframes registered
  // while the pose graph is solved then match their neighbours.
  const auto hood_scale = [&corr, s = corrected_q.scale()](KeyframeId id) { return corr.corrected.count(id) ? s : 1.0; };
  RescaleHandlers(stack, *smap, hood_scale);
  smap->RescaleAnchors(hood_scale);

  PointFusionResult fusion;
  FuseVerifiedMatches(&map, *c, *q, d.matches, &fusion);
  const auto loop_points = PointsAround(map, c, 10);
  for (const auto& n : hood) FusePointsIntoKeyframe(&map, n, GridOf(*n), loop_points, kLoopFusionRadiusPx, &fusion);
  for (const auto& [old_id, keep] : fusion.replaced) smap->RecordReplacement(old_id, keep);
  r.points_fused = fusion.fused + fusion.linked;

  std::set<KeyframeId> hood_ids;
  for (const auto& n : hood) hood_ids.insert(n->id());
  for (const auto& n : hood) {
    map.UpdateConnections(n->id());
    for (const auto& [m, w] : n->covisibility()) {
      if (!hood_ids.count(m) && !links_before[n->id()].count(m)) corr.loop_connections.emplace_back(n->id(), m);
    }
  }
  map.AddLoopEdge(q->id(), c->id());
  corr.loop_connections.emplace_back(q->id(), c->id());
  corr.fixed = c->id();
  r.neighbourhood = static_cast<int>(hood.size());
  r.loop_connections = static_cast<int>(corr.loop_connections.size());

  // The pose graph is solved with the lock released: registration goes on meanwhile (its
  // keyframes hang off the corrected neighbourhood and follow their ancestor's correction).
  // The generation bump makes a global BA snapshot taken before this point come back stale;
  // the caller holds new ones back until the loop is applied.
  EssentialGraphProblem graph = BuildEssentialGraphProblem(map, corr);
  smap->BumpGeneration();
  r.locked_s = SecondsSince(t_locked);
  lock.unlock();

  opt::PoseGraphOptions pg;
  pg.max_iterations = options.optimization.pose_graph_iterations;
  CorrectionResult result = SolveEssentialGraph(std::move(graph), pg);
  r.pose_graph_s = result.seconds;

  lock.lock();
  t_locked = Clock::now();
  if (result.ok && !smap->retired()) {
    // Points moved with the neighbourhood are consistent with the keyframe that moved them.
    for (const auto& [mp, kf] : moved_by) result.point_reference.emplace(mp, kf);
    r.keyframes_added_meanwhile = ApplyCorrection(&map, result).keyframes_added_meanwhile;
    smap->RescaleAnchors([&result](KeyframeId root) {
      const auto o = result.optimized.find(root), i = result.initial.find(root);
      return o != result.optimized.end() && i != result.initial.end() ? o->second.scale() / i->second.scale() : 1.0;
    });
  }
  const SE3 query_after = q->world_from_cam();
  r.correction_m = (query_after.translation() - query_before.translation()).norm();
  r.correction_deg =
      Eigen::AngleAxisd(query_before.rotation().conjugate() * query_after.rotation()).angle() * 180.0 / M_PI;
  r.scale_correction = result.ok ? result.optimized.at(q->id()).scale() : corrected_q.scale();

  if (result.ok) {
    RescaleHandlers(stack, *smap, [&](KeyframeId node) {
      const KeyframeId anc =
          SpanningTreeAncestor(map, node, [&result](KeyframeId id) { return result.optimized.count(id) > 0; });
      return anc.valid() ? result.optimized.at(anc).scale() / result.initial.at(anc).scale() : 1.0;
    });
  }
  std::vector<KeyframeId> all;
  for (const auto& kf : map.keyframes()) all.push_back(kf->id());
  smap->MarkSettled(all);
  smap->BumpGeneration();
  r.closed = true;
  r.locked_s += SecondsSince(t_locked);
  r.seconds = SecondsSince(t0);
  return r;
}

}  // namespace ccm
