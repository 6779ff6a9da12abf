#include "slam_core/server/map_fuser.h"

#include <chrono>
#include <unordered_set>

#include "slam_core/vo/point_fusion.h"

namespace ccm {
namespace {

constexpr double kFusionRadiusPx = 4.0;
constexpr int kOverlapNeighbours = 10;

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

}  // namespace

FusionReport FuseMaps(MapStack* stack, const PlaceDetection& d,
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
  const Sim3 S = move_candidate_map ? q_from_c : q_from_c.inverse();
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
    mp->SetPosition(S * mp->position());
    dst.AddMapPoint(mp);
    ++r.points_moved;
  }
  kept->AbsorbTables(absorbed);

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
