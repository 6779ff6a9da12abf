#include "tools/replay/replay_report.h"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "slam_core/eval/evaluator.h"
#include "slam_core/io/trajectory_io.h"
#include "tools/replay/map_drawing.h"

namespace ccm::replay {
namespace {

std::vector<SE3> Poses(const Trajectory& t) {
  std::vector<SE3> out;
  for (const auto& p : t) out.push_back(p.world_from_cam);
  return out;
}

Trajectory InMap(const std::vector<ServerKeyframePose>& kfs, MapId map) {
  Trajectory t;
  for (const auto& k : kfs) {
    if (k.map == map) t.push_back({k.stamp_ns, k.world_from_cam});
  }
  return t;
}

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"max", s.max}, {"count", s.count}};
}

}  // namespace

ReplayEvaluation EvaluateReplay(const ReplayResult& result) {
  ReplayEvaluation ev;
  ev.maps = result.maps.size();
  size_t best = 0;
  for (const MapSummary& m : result.maps) {
    if (m.keyframes + m.anchored > best) best = m.keyframes + m.anchored, ev.final_map = m.id;
  }
  EvalOptions eo;
  std::vector<AgentInput> joint;
  double standalone_sum = 0.0;
  int standalone_n = 0;
  for (const ReplayAgentResult& a : result.agents) {
    AgentScore s;
    s.name = a.name;
    s.id = a.id;
    s.path_m = PathLengthM(Poses(a.ground_truth));
    s.vo_keyframes = a.vo_keyframes.size();
    const Trajectory in_map = InMap(a.server_keyframes, ev.final_map);
    s.server_keyframes = in_map.size();
    ev.joint_path_m += s.path_m;
    if (!a.ground_truth.empty()) {
      ev.has_ground_truth = true;
      EvalReport rep;
      std::string error;
      if (a.vo_keyframes.size() >= 3 && Evaluate({{a.name, a.ground_truth, a.vo_keyframes}}, eo, &rep, &error)) {
        s.standalone_ate_m = rep.agents[0].ate_m;
        standalone_sum += s.standalone_ate_m.rmse;
        ++standalone_n;
      }
      if (in_map.size() >= 3) joint.push_back({a.name, a.ground_truth, in_map});
    }
    ev.agents.push_back(s);
  }
  ev.mean_standalone_ate_m = standalone_n ? standalone_sum / standalone_n : 0.0;
  if (!joint.empty()) {
    EvalReport rep;
    std::string error;
    if (Evaluate(joint, eo, &rep, &error)) {
      ev.collaborative_ate_m = rep.joint.ate_m;
      ev.gt_from_map = rep.joint.gt_from_est;
      for (const AgentResult& r : rep.agents) {
        for (AgentScore& s : ev.agents) {
          if (s.name == r.name) s.collaborative_ate_m = r.ate_joint_m;
        }
      }
      if (ev.joint_path_m > 0) ev.collaborative_ate_percent = 100.0 * ev.collaborative_ate_m.rmse / ev.joint_path_m;
    } else {
      ev.note = error;
    }
  } else if (!ev.has_ground_truth) {
    ev.note = "no ground truth: accuracy not scored";
  }
  return ev;
}

bool WriteReplayOutputs(const std::string& dir, const ReplayResult& result, const ReplayEvaluation& ev,
                        const ServerBackend& backend, std::string* error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    *error = "cannot create " + dir + ": " + ec.message();
    return false;
  }
  nlohmann::json agents = nlohmann::json::array();
  for (size_t i = 0; i < result.agents.size(); ++i) {
    const ReplayAgentResult& a = result.agents[i];
    const std::string file = a.name + "_keyframes.tum";
    Trajectory t = InMap(a.server_keyframes, ev.final_map);
    if (const IoStatus s = WriteTumTrajectory(dir + "/" + file, t); !s.ok()) {
      *error = s.message();
      return false;
    }
    if (!a.ground_truth.empty()) {
      if (const IoStatus s = WriteTumTrajectory(dir + "/" + a.name + "_ground_truth.tum", a.ground_truth); !s.ok()) {
        *error = s.message();
        return false;
      }
    }
    const AgentScore& sc = ev.agents[i];
    const auto counters = result.stats.agents.count(a.id) ? result.stats.agents.at(a.id) : AgentCounters{};
    agents.push_back({{"name", a.name},
                      {"id", a.id},
                      {"frames", a.frames},
                      {"frames_tracked", a.frames_tracked},
                      {"segments", a.segments},
                      {"keyframes_created", a.keyframes_created},
                      {"keyframes_registered", counters.keyframes_registered},
                      {"keyframes_sent_as_anchors", counters.keyframes_anchor_only},
                      {"keyframes_skipped_as_duplicates", counters.keyframes_duplicate},
                      {"keyframes_in_final_map", sc.server_keyframes},
                      {"path_m", sc.path_m},
                      {"standalone_ate_m", StatsJson(sc.standalone_ate_m)},
                      {"collaborative_ate_m", StatsJson(sc.collaborative_ate_m)},
                      {"tracking_ms_median", Percentile(a.tracking_ms, 0.5)},
                      {"server_keyframe_ms_median", Percentile(counters.keyframe_ms, 0.5)},
                      {"server_keyframe_ms_p95", Percentile(counters.keyframe_ms, 0.95)},
                      {"trajectory", file}});
  }
  nlohmann::json events = nlohmann::json::array();
  for (const ServerEvent& e : result.events) {
    events.push_back({{"kind", ServerEventKindName(e.kind)},
                      {"time_s", e.time_s},
                      {"stamp_ns", e.stamp_ns},
                      {"agent", e.agent},
                      {"map", e.map.counter()},
                      {"other_map", e.other_map.counter()},
                      {"keyframes", e.keyframes},
                      {"seconds", e.seconds},
                      {"detail", e.detail}});
  }
  nlohmann::json maps = nlohmann::json::array();
  for (const MapSummary& m : result.maps) {
    maps.push_back({{"id", m.id.counter()},
                    {"keyframes", m.keyframes},
                    {"anchored_keyframes", m.anchored},
                    {"map_points", m.map_points},
                    {"agents", std::vector<int>(m.agents.begin(), m.agents.end())}});
  }
  nlohmann::json gba = nlohmann::json::array();
  for (const auto& [kfs, s] : result.stats.global_ba_seconds) gba.push_back({{"keyframes", kfs}, {"seconds", s}});
  const nlohmann::json summary = {
      {"wall_s", result.wall_s},
      {"final_map", ev.final_map.counter()},
      {"maps", maps},
      {"fusions", result.stats.fusions},
      {"loops", result.stats.loops},
      {"keyframes_removed_as_redundant", result.stats.keyframes_removed},
      {"global_ba", {{"applied", result.stats.global_ba_applied},
                     {"aborted", result.stats.global_ba_aborted},
                     {"stale", result.stats.global_ba_stale},
                     {"runs", gba}}},
      {"accuracy", {{"has_ground_truth", ev.has_ground_truth},
                    {"joint_path_m", ev.joint_path_m},
                    {"collaborative_ate_m", StatsJson(ev.collaborative_ate_m)},
                    {"collaborative_ate_percent_of_path", ev.collaborative_ate_percent},
                    {"mean_standalone_ate_m", ev.mean_standalone_ate_m},
                    {"note", ev.note}}},
      {"agents", agents},
      {"events", events}};
  std::ofstream out(dir + "/summary.json");
  out << summary.dump(2) << "\n";
  if (!out) {
    *error = "cannot write " + dir + "/summary.json";
    return false;
  }
  return WriteMapPly(dir + "/map.ply", backend, ev.final_map, error) &&
         WriteMapTopView(dir + "/map_top.png", result, ev, backend, error);
}

}  // namespace ccm::replay
