#include "slam_core/server/map_correction.h"

#include <set>

namespace ccm {

EssentialGraphProblem BuildEssentialGraphProblem(const Map& map, const EssentialGraphCorrection& c) {
  EssentialGraphProblem problem;
  const EssentialGraph graph = map.BuildEssentialGraph();
  std::unordered_map<KeyframeId, int> index;
  std::vector<Sim3> before;
  for (const KeyframeId id : graph.nodes) {
    const auto kf = map.keyframe(id);
    if (!kf) continue;
    const auto b = c.before.find(id);
    const SE3 pose_before = b != c.before.end() ? b->second : kf->world_from_cam();
    const auto corr = c.corrected.find(id);
    opt::Sim3Node node;
    node.id = id.packed();
    node.world_from_cam = corr != c.corrected.end() ? corr->second : Sim3(kf->world_from_cam());
    node.fixed = id == c.fixed;
    index.emplace(id, static_cast<int>(problem.nodes.size()));
    problem.nodes.push_back(node);
    before.push_back(Sim3(pose_before));
  }
  std::set<std::pair<KeyframeId, KeyframeId>> loop_set;
  for (auto [a, b] : c.loop_connections) {
    if (b < a) std::swap(a, b);
    loop_set.emplace(a, b);
  }
  auto add_edge = [&](KeyframeId a, KeyframeId b, bool from_corrected, opt::Sim3EdgeKind kind) {
    const auto ia = index.find(a), ib = index.find(b);
    if (ia == index.end() || ib == index.end()) return;
    opt::Sim3Edge e;
    e.i = ia->second;
    e.j = ib->second;
    const Sim3& si = from_corrected ? problem.nodes[e.i].world_from_cam : before[e.i];
    const Sim3& sj = from_corrected ? problem.nodes[e.j].world_from_cam : before[e.j];
    e.i_from_j = si.inverse() * sj;
    e.kind = kind;
    problem.edges.push_back(e);
  };
  for (const auto& e : graph.edges) {
    auto key = e.a < e.b ? std::make_pair(e.a, e.b) : std::make_pair(e.b, e.a);
    if (loop_set.count(key)) continue;  // added below, measured after the correction
    const bool loop = e.type == EssentialGraph::EdgeType::kLoop;
    add_edge(e.a, e.b, false,
             loop ? opt::Sim3EdgeKind::kLoop
                  : e.type == EssentialGraph::EdgeType::kSpanningTree ? opt::Sim3EdgeKind::kSpanningTree
                                                                      : opt::Sim3EdgeKind::kCovisibility);
  }
  for (const auto& [a, b] : loop_set) add_edge(a, b, true, opt::Sim3EdgeKind::kLoop);
  return problem;
}

CorrectionResult SolveEssentialGraph(EssentialGraphProblem problem, const opt::PoseGraphOptions& options) {
  CorrectionResult out;
  for (const auto& n : problem.nodes) out.initial.emplace(KeyframeId(n.id), n.world_from_cam);
  out.nodes = static_cast<int>(problem.nodes.size());
  out.edges = static_cast<int>(problem.edges.size());
  if (problem.edges.empty()) return out;
  const opt::OptimizationSummary s = opt::OptimizePoseGraph(&problem, options);
  out.ok = s.usable;
  out.iterations = s.iterations;
  out.seconds = s.solve_time_s;
  if (!out.ok) return out;
  for (const auto& n : problem.nodes) out.optimized.emplace(KeyframeId(n.id), n.world_from_cam);
  return out;
}

ApplyCorrectionReport ApplyCorrection(Map* map, const CorrectionResult& r) {
  ApplyCorrectionReport rep;
  std::unordered_map<KeyframeId, Sim3> delta;  // world-frame correction S_opt * S_initial^-1
  for (const auto& [id, s] : r.optimized) delta.emplace(id, s * r.initial.at(id).inverse());
  const auto corrected = [&delta](KeyframeId id) { return delta.count(id) > 0; };
  for (const auto& kf : map->keyframes()) {
    const KeyframeId anc = SpanningTreeAncestor(*map, kf->id(), corrected);
    if (!anc.valid()) continue;
    ++rep.keyframes;
    rep.keyframes_added_meanwhile += anc != kf->id();
    kf->SetWorldFromCam(opt::RigidPose(delta.at(anc) * Sim3(kf->world_from_cam())));
  }
  for (const auto& mp : map->map_points()) {
    const auto override_it = r.point_reference.find(mp->id());
    KeyframeId ref = override_it != r.point_reference.end() ? override_it->second
                                                            : SpanningTreeAncestor(*map, mp->reference_kf(), corrected);
    if (!corrected(ref)) {
      ref = KeyframeId::Invalid();
      for (const auto& [kf, idx] : mp->observations()) {
        if (corrected(kf)) {
          ref = kf;
          break;
        }
      }
      if (!ref.valid()) continue;
    }
    ++rep.points;
    mp->SetPosition(delta.at(ref) * mp->position());
  }
  return rep;
}

}  // namespace ccm
