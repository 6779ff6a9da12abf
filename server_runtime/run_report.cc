#include "server_runtime/run_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "slam_core/eval/evaluator.h"

namespace ccm::report {
namespace {

std::vector<SE3> Poses(const Trajectory& t) {
  std::vector<SE3> out;
  for (const auto& p : t) out.push_back(p.world_from_cam);
  return out;
}

// Ground-truth path between two stamps: what the part of a flight that a map holds covered.
double PathBetween(const Trajectory& gt, int64_t from_ns, int64_t to_ns) {
  std::vector<SE3> poses;
  for (const auto& p : gt) {
    if (p.stamp_ns >= from_ns && p.stamp_ns <= to_ns) poses.push_back(p.world_from_cam);
  }
  return PathLengthM(poses);
}

MapScore ScoreMap(const RunResult& result, const MapSummary& summary) {
  MapScore ms;
  ms.summary = summary;
  std::vector<AgentInput> joint;
  for (const AgentRunResult& a : result.agents) {
    const Trajectory t = KeyframesInMap(a.server_keyframes, summary.id);
    if (t.empty() && !summary.agents.count(a.id)) continue;
    AgentInMap part;
    part.name = a.name;
    part.id = a.id;
    part.keyframes = t.size();
    for (const ServerKeyframePose& k : a.server_keyframes) {  // t is not empty when one matches
      if (k.map != summary.id || !k.in_map) continue;
      part.full_keyframe_s.push_back(std::round((k.stamp_ns - t.front().stamp_ns) * 1e-8) / 10.0);
    }
    if (!a.ground_truth.empty() && !t.empty()) part.path_m = PathBetween(a.ground_truth, t.front().stamp_ns, t.back().stamp_ns);
    // Three keyframes at least: fewer cannot fix a Sim(3) of their own (the scale).
    if (!a.ground_truth.empty() && t.size() >= 3) joint.push_back({a.name, a.ground_truth, t});
    ms.path_m += part.path_m;
    ms.agents.push_back(part);
  }
  if (joint.empty()) return ms;
  EvalReport rep;
  std::string error;
  if (!Evaluate(joint, EvalOptions{}, &rep, &error)) {
    ms.note = error;
    return ms;
  }
  ms.scored = true;
  ms.joint_ate_m = rep.joint.ate_m;
  ms.gt_from_map = rep.joint.gt_from_est;
  if (ms.path_m > 0) ms.joint_ate_percent = 100.0 * ms.joint_ate_m.rmse / ms.path_m;
  double lo = 0.0, hi = 0.0;
  for (const AgentResult& r : rep.agents) {
    for (AgentInMap& part : ms.agents) {
      if (part.name != r.name) continue;
      part.ate_m = r.ate_joint_m;
      part.own_ate_m = r.ate_m;
      part.scale_to_gt = r.gt_from_est.scale();
      lo = lo > 0.0 ? std::min(lo, part.scale_to_gt) : part.scale_to_gt;
      hi = std::max(hi, part.scale_to_gt);
    }
  }
  if (rep.agents.size() >= 2 && lo > 0.0) ms.scale_ratio = hi / lo;
  return ms;
}

}  // namespace

Trajectory KeyframesInMap(const std::vector<ServerKeyframePose>& kfs, MapId map) {
  Trajectory t;
  for (const auto& k : kfs) {
    if (k.map == map) t.push_back({k.stamp_ns, k.world_from_cam});
  }
  return t;
}

std::string MapTrajectoryFile(MapId map, const std::string& agent) {
  return "map" + std::to_string(map.counter()) + "_" + agent + "_keyframes.tum";
}

std::string MapPlyFile(const RunEvaluation& ev, MapId map) {
  return map == ev.final_map ? std::string("map.ply") : "map" + std::to_string(map.counter()) + ".ply";
}

RunEvaluation EvaluateRun(const RunResult& result) {
  RunEvaluation ev;
  ev.maps = result.maps.size();
  std::vector<MapSummary> maps = result.maps;
  // Largest first; on a tie the map listed first stays first (the final map before maps
  // were listed was the first of the largest).
  std::stable_sort(maps.begin(), maps.end(), [](const MapSummary& a, const MapSummary& b) {
    return a.keyframes + a.anchored > b.keyframes + b.anchored;
  });
  for (const MapSummary& m : maps) ev.map_scores.push_back(ScoreMap(result, m));
  if (!maps.empty()) ev.final_map = maps.front().id;
  double standalone_sum = 0.0;
  int standalone_n = 0;
  for (const AgentRunResult& a : result.agents) {
    AgentScore s;
    s.name = a.name;
    s.id = a.id;
    s.path_m = PathLengthM(Poses(a.ground_truth));
    s.vo_keyframes = a.vo_keyframes.size();
    s.server_keyframes = KeyframesInMap(a.server_keyframes, ev.final_map).size();
    ev.joint_path_m += s.path_m;
    if (!a.ground_truth.empty()) {
      ev.has_ground_truth = true;
      EvalReport rep;
      std::string error;
      if (a.vo_keyframes.size() >= 3 && Evaluate({{a.name, a.ground_truth, a.vo_keyframes}}, EvalOptions{}, &rep, &error)) {
        s.standalone_ate_m = rep.agents[0].ate_m;
        standalone_sum += s.standalone_ate_m.rmse;
        ++standalone_n;
      }
    }
    ev.agents.push_back(s);
  }
  ev.mean_standalone_ate_m = standalone_n ? standalone_sum / standalone_n : 0.0;
  // The final map's scores are the run's headline numbers (as before every map was scored).
  if (!ev.map_scores.empty() && ev.map_scores.front().scored) {
    const MapScore& fm = ev.map_scores.front();
    ev.collaborative_ate_m = fm.joint_ate_m;
    ev.gt_from_map = fm.gt_from_map;
    for (const AgentInMap& part : fm.agents) {
      for (AgentScore& s : ev.agents) {
        if (s.id != part.id) continue;
        s.collaborative_ate_m = part.ate_m;
        s.part_ate_m = part.own_ate_m;
      }
    }
    if (ev.joint_path_m > 0) ev.collaborative_ate_percent = 100.0 * ev.collaborative_ate_m.rmse / ev.joint_path_m;
  } else if (!ev.map_scores.empty() && !ev.map_scores.front().note.empty()) {
    ev.note = ev.map_scores.front().note;
  } else if (!ev.has_ground_truth) {
    ev.note = "no ground truth: accuracy not scored";
  }
  return ev;
}

void PrintRunSummary(const RunResult& r, const RunEvaluation& ev) {
  // "ATE map": the agent's keyframes under the map's one alignment; "ATE part": under their
  // own (the agent's part of the map against its VO, whatever the other parts do).
  std::printf("\n%-12s %7s %8s %6s %10s %10s %12s %12s %13s\n", "agent", "frames", "tracked", "segs", "KFs VO",
              "KFs map", "ATE VO [m]", "ATE map [m]", "ATE part [m]");
  for (size_t i = 0; i < r.agents.size(); ++i) {
    const auto& a = r.agents[i];
    const auto& s = ev.agents[i];
    std::printf("%-12s %7lld %7.1f%% %6d %10zu %10zu %12.4f %12.4f %13.4f\n", a.name.c_str(),
                static_cast<long long>(a.frames), a.frames ? 100.0 * a.frames_tracked / a.frames : 0.0, a.segments,
                s.vo_keyframes, s.server_keyframes, s.standalone_ate_m.rmse, s.collaborative_ate_m.rmse,
                s.part_ate_m.rmse);
  }
  std::printf("maps %zu, fusions %lld, loops %lld, redundant keyframes removed %lld, global BAs %lld (%lld aborted)\n",
              ev.maps, static_cast<long long>(r.stats.fusions), static_cast<long long>(r.stats.loops),
              static_cast<long long>(r.stats.keyframes_removed), static_cast<long long>(r.stats.global_ba_applied),
              static_cast<long long>(r.stats.global_ba_aborted));
  const PlaceMatcherStats& p = r.stats.place;
  std::string stopped;
  for (int s = 0; s < kNumVerificationStages; ++s) {
    if (p.fusion_stopped_at[s] == 0) continue;
    stopped += std::string(stopped.empty() ? "" : ", ") +
               VerificationStageName(static_cast<VerificationStage>(s)) + " " +
               std::to_string(p.fusion_stopped_at[s]);
  }
  std::printf("place recognition: %lld queries, %lld fusion / %lld loop candidates, %lld verified, %lld inconsistent, "
              "%lld fusions / %lld loops accepted; fusion candidates stopped at: %s\n",
              static_cast<long long>(p.queries), static_cast<long long>(p.match_candidates),
              static_cast<long long>(p.loop_candidates), static_cast<long long>(p.verified),
              static_cast<long long>(p.inconsistent), static_cast<long long>(p.accepted_fusions),
              static_cast<long long>(p.accepted_loops), stopped.empty() ? "none" : stopped.c_str());
  // Every map with its agents: an agent that never fused shows up in a map of its own.
  for (const auto& ms : ev.map_scores) {
    std::string agents;
    for (const auto& part : ms.agents) {
      agents += (agents.empty() ? "" : ", ") + part.name + " (" + std::to_string(part.keyframes) + " KFs)";
    }
    std::printf("  map %llu%s: %zu keyframes (%zu anchored), %zu points; agents %s\n",
                static_cast<unsigned long long>(ms.summary.id.counter()), ms.summary.id == ev.final_map ? " (largest)" : "",
                ms.summary.keyframes + ms.summary.anchored, ms.summary.anchored, ms.summary.map_points,
                agents.empty() ? "none" : agents.c_str());
    if (ms.scored) {
      std::printf("    joint ATE %.4f m = %.3f%% of %.1f m%s", ms.joint_ate_m.rmse, ms.joint_ate_percent, ms.path_m,
                  ms.scale_ratio > 0 ? "" : "\n");
      if (ms.scale_ratio > 0) std::printf(", scale ratio between the agents' parts %.3f\n", ms.scale_ratio);
    }
  }
  if (ev.collaborative_ate_m.count > 0) {
    std::printf("collaborative ATE %.4f m = %.4f%% of %.1f m joint path (mean standalone VO ATE %.4f m)\n",
                ev.collaborative_ate_m.rmse, ev.collaborative_ate_percent, ev.joint_path_m, ev.mean_standalone_ate_m);
  } else if (!ev.note.empty()) {
    std::printf("accuracy: %s\n", ev.note.c_str());
  }
  for (const auto& e : r.events) {
    if (e.kind == ServerEvent::Kind::kGlobalBa) continue;
    std::printf("  t=%6.1fs %-8s agent %u map %llu %s\n", e.time_s, ServerEventKindName(e.kind), e.agent,
                static_cast<unsigned long long>(e.map.counter()), e.detail.c_str());
  }
}

}  // namespace ccm::report
