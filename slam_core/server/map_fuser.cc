#include "slam_core/server/map_fuser.h"

#include <chrono>
#include <set>
#include <unordered_set>

#include "slam_core/map_ops/keyframe_matching.h"
#include "slam_core/map_ops/point_fusion.h"
#include "slam_core/server/overlap_weld.h"
#include "slam_core/solvers/similarity.h"

namespace ccm {
namespace {

constexpr double kFusionRadiusPx = 4.0;
constexpr int kOverlapNeighbours = 10;
constexpr double kRefineRadiusPx = 8.0;

std::vector<std::shared_ptr<KeyFrame>> Around(const Map& map, const std::shared_ptr<KeyFrame>& kf) {
  std::vector<std::shared_ptr<KeyFrame>> out{kf};
  for (const KeyframeId id : kf->BestCovisible(kOverlapNeighbours)) {
    if (const auto n = map.keyframe(id)) out.push_back(n);
  }
  return out;
}

std::vector<std::shared_ptr<MapPoint>> PointsOfAll(const Map& map, const std::vector<std::shared_ptr<KeyFrame>>& kfs) {
  std::vector<std::shared_ptr<MapPoint>> out;
  std::unordered_set<MapPointId> seen;
  for (const auto& k : kfs) {
    for (const auto& mp : PointsOf(map, *k)) {
      if (seen.insert(mp->id()).second) out.push_back(mp);
    }
  }
  return out;
}

// The verified Sim(3) rests on one keyframe pair; the overlap usually shows much more.
// With the absorbed map already moved by it, the candidate's neighbourhood points are
// matched into the query's neighbourhood keyframes, and a Sim(3) fitted robustly to all
// 3D-3D pairs (in the query camera's frame, inliers within 5 % of their depth) gives the
// residual correction (near identity). Rotation and scale of a map-to-map transform come
// out far better from points spread over 20 keyframes than over one view.
std::optional<Sim3> RefineOverlap(const Map& map, const std::vector<std::shared_ptr<KeyFrame>>& around_q,
                                  const std::vector<std::shared_ptr<MapPoint>>& points_c, const KeyFrame& q,
                                  int* pairs, int* inliers) {
  const SE3 q_from_world = q.cam_from_world();
  std::vector<Eigen::Vector3d> a, b;  // a: absorbed point, b: kept point; both in q's camera frame
  for (const auto& kf : around_q) {
    for (const auto& [mp, idx] : MatchPointsIntoKeyframe(*kf, GridOf(*kf), points_c, kRefineRadiusPx)) {
      const MapPointId own = kf->MapPointAt(idx);
      const auto kept = own.valid() ? map.map_point(own) : nullptr;
      if (!kept || kept == mp) continue;
      a.push_back(q_from_world * mp->position());
      b.push_back(q_from_world * kept->position());
    }
  }
  *pairs = static_cast<int>(a.size());
  if (a.size() < 30) return std::nullopt;
  solvers::Sim3Options o;
  o.metric = solvers::Sim3InlierMetric::kRelativeDistance;
  o.max_relative_distance = 0.05;
  o.ransac.max_iterations = 200;
  o.min_inliers = 30;
  const solvers::Sim3Result r = solvers::EstimateSim3(a, b, o);
  *inliers = r.num_inliers;
  if (!r.ok() || r.num_inliers < static_cast<int>(a.size()) / 3) return std::nullopt;
  // A plausible residual only: the verification already put the maps within a few pixels.
  const double angle_deg = Eigen::AngleAxisd(r.b_from_a.rotation()).angle() * 180.0 / M_PI;
  if (angle_deg > 5.0 || std::abs(std::log(r.b_from_a.scale())) > 0.1) return std::nullopt;
  const Sim3 world_from_q(q.world_from_cam());
  return world_from_q * r.b_from_a * world_from_q.inverse();
}

// A point moved by a similarity: position, viewing direction and the distance range in
// which it can be matched (projection matching checks both).
void TransformPoint(MapPoint* mp, const Sim3& S) {
  mp->SetPosition(S * mp->position());
  mp->SetAppearance(mp->descriptor(), S.rotation() * mp->normal(), S.scale() * mp->min_distance_m(),
                    S.scale() * mp->max_distance_m());
}

}  // namespace

FusionReport FuseMaps(MapStack* stack, const PlaceDetection& d, double weld_depth_ratio,
                      const std::function<void(MapId absorbed, MapId kept)>& on_fused) {
  const auto t0 = std::chrono::steady_clock::now();
  FusionReport r;
  r.query = d.query;
  r.candidate = d.candidate;
  auto mq = stack->GetMap(d.query_map), mc = stack->GetMap(d.candidate_map);
  if (!mq || !mc || mq == mc) {
    r.reason = "maps changed since the detection";
    return r;
  }
  ServerMap* first = mq->id() < mc->id() ? mq.get() : mc.get();
  ServerMap* second = first == mq.get() ? mc.get() : mq.get();
  std::unique_lock<WriterPreferringMutex> lock1(first->structure_mutex());
  std::unique_lock<WriterPreferringMutex> lock2(second->structure_mutex());
  const auto q = mq->map().keyframe(d.query), c = mc->map().keyframe(d.candidate);
  if (mq->retired() || mc->retired() || !q || !c) {
    r.reason = "query or candidate left its map";
    return r;
  }
  // p_q_map = S * p_c_map, through the two keyframes and the verified camera-frame Sim(3).
  const Sim3 q_from_c = Sim3(q->world_from_cam()) * d.query_from_candidate * Sim3(c->cam_from_world());
  const bool move_candidate_map = mc->map().num_keyframes() <= mq->map().num_keyframes();
  ServerMap* kept = move_candidate_map ? mq.get() : mc.get();
  ServerMap* absorbed = move_candidate_map ? mc.get() : mq.get();
  Sim3 S = move_candidate_map ? q_from_c : q_from_c.inverse();
  r.kept = kept->id();
  r.absorbed = absorbed->id();
  r.kept_from_absorbed = S;

  Map& dst = kept->map();
  for (const auto& kf : absorbed->map().keyframes()) {
    kf->SetWorldFromCam(S.TransformPose(kf->world_from_cam()));
    dst.AddKeyframe(kf);
    ++r.keyframes_moved;
  }
  for (const auto& mp : absorbed->map().map_points()) {
    TransformPoint(mp.get(), S);
    dst.AddMapPoint(mp);
    ++r.points_moved;
  }
  absorbed->RescaleAnchors([&S](KeyframeId) { return S.scale(); });
  kept->AbsorbTables(absorbed);

  std::set<KeyframeId> absorbed_ids;
  for (const auto& kf : absorbed->map().keyframes()) absorbed_ids.insert(kf->id());
  // Refine the transform on the whole overlap before anything is merged.
  {
    const auto candidate_points = PointsOfAll(dst, Around(dst, c));
    if (const auto q_side_from_c_side =
            RefineOverlap(dst, Around(dst, q), candidate_points, *q, &r.overlap_pairs, &r.overlap_inliers)) {
      // It moves the candidate's side onto the query's; the absorbed map is either one.
      const Sim3 delta = move_candidate_map ? *q_side_from_c_side : q_side_from_c_side->inverse();
      for (const KeyframeId id : absorbed_ids) {
        const auto kf = dst.keyframe(id);
        kf->SetWorldFromCam(delta.TransformPose(kf->world_from_cam()));
      }
      for (const auto& mp : absorbed->map().map_points()) TransformPoint(mp.get(), delta);
      kept->RescaleAnchors([&](KeyframeId root) { return absorbed_ids.count(root) ? delta.scale() : 1.0; });
      S = delta * S;
      r.kept_from_absorbed = S;
      r.refined = true;
    }
  }

  // Merge the overlap: the verified matches first, then everything that projects.
  PointFusionResult fusion;
  for (const FeatureMatch& m : d.matches) {
    const MapPointId cp = c->MapPointAt(m.index1), qp = q->MapPointAt(m.index2);
    if (!cp.valid() || !qp.valid() || cp == qp) continue;
    const auto a = dst.map_point(cp), b = dst.map_point(qp);
    if (!a || !b) continue;
    const bool keep_c = a->num_observations() >= b->num_observations();
    const MapPointId old_id = keep_c ? qp : cp, keep = keep_c ? cp : qp;
    if (dst.ReplaceMapPoint(old_id, keep)) {
      ++fusion.fused;
      fusion.replaced.emplace_back(old_id, keep);
    }
  }
  const auto around_q = Around(dst, q), around_c = Around(dst, c);
  const auto points_q = PointsOfAll(dst, around_q), points_c = PointsOfAll(dst, around_c);
  for (const auto& kf : around_q) FusePointsIntoKeyframe(&dst, kf, GridOf(*kf), points_c, kFusionRadiusPx, &fusion);
  for (const auto& kf : around_c) FusePointsIntoKeyframe(&dst, kf, GridOf(*kf), points_q, kFusionRadiusPx, &fusion);
  for (const auto& [old_id, keep] : fusion.replaced) kept->RecordReplacement(old_id, keep);
  for (const auto& kf : around_q) dst.UpdateConnections(kf->id());
  for (const auto& kf : around_c) dst.UpdateConnections(kf->id());
  // Then the rest of the overlap, wherever the two sides saw the same scene.
  if (weld_depth_ratio > 0.0) {
    OverlapWeldOptions wo;
    wo.max_centre_depth_ratio = weld_depth_ratio;
    wo.radius_px = kFusionRadiusPx;
    const OverlapWeldReport weld = WeldOverlap(&dst, absorbed_ids, wo);
    for (const auto& [old_id, keep] : weld.fusion.replaced) kept->RecordReplacement(old_id, keep);
    fusion.fused += weld.fusion.fused;
    fusion.linked += weld.fusion.linked;
    r.weld_targets = weld.targets;
    r.weld_merged = weld.fusion.fused + weld.fusion.linked;
  }
  dst.AddLoopEdge(q->id(), c->id());
  r.points_merged = fusion.fused + fusion.linked;

  absorbed->Retire();
  stack->Repoint(absorbed->id(), kept->id(), S);
  if (on_fused) on_fused(absorbed->id(), kept->id());
  kept->BumpGeneration();
  absorbed->BumpGeneration();
  r.fused = true;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace ccm
