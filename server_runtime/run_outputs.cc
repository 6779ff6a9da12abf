// WriteRunOutputs (run_report.h): the files a replay or a stopped server leaves.
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "slam_core/io/trajectory_io.h"
#include "server_runtime/map_drawing.h"
#include "server_runtime/run_report.h"

namespace ccm::report {
namespace {

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"max", s.max}, {"count", s.count}};
}

const AgentRunResult* FindAgent(const RunResult& result, AgentId id) {
  for (const AgentRunResult& a : result.agents) {
    if (a.id == id) return &a;
  }
  return nullptr;
}

bool WriteTum(const std::string& path, const Trajectory& t, std::string* error) {
  if (const IoStatus s = WriteTumTrajectory(path, t); !s.ok()) {
    *error = s.message();
    return false;
  }
  return true;
}

// Every map, largest first: sizes, its agents' parts with their trajectory files, and the
// accuracy of the map on its own (null without ground truth).
nlohmann::json MapsJson(const RunEvaluation& ev) {
  nlohmann::json maps = nlohmann::json::array();
  for (const MapScore& ms : ev.map_scores) {
    const MapSummary& m = ms.summary;
    nlohmann::json parts = nlohmann::json::array();
    std::vector<int> agent_ids;
    for (const AgentInMap& p : ms.agents) {
      agent_ids.push_back(static_cast<int>(p.id));
      nlohmann::json part = {{"name", p.name}, {"id", p.id}, {"keyframes", p.keyframes},
                             {"full_keyframes", p.full_keyframe_s.size()}, {"full_keyframe_s", p.full_keyframe_s},
                             {"trajectory", p.keyframes ? MapTrajectoryFile(m.id, p.name) : ""}};
      if (ms.scored) {
        part["path_m"] = p.path_m;
        part["ate_m"] = StatsJson(p.ate_m);
        part["own_ate_m"] = StatsJson(p.own_ate_m);
        part["scale_to_ground_truth"] = p.scale_to_gt;
      }
      parts.push_back(part);
    }
    nlohmann::json accuracy = nullptr;
    if (ms.scored) {
      accuracy = {{"joint_ate_m", StatsJson(ms.joint_ate_m)},
                  {"path_m", ms.path_m},
                  {"joint_ate_percent_of_path", ms.joint_ate_percent},
                  {"scale_ratio", ms.scale_ratio}};
    } else if (!ms.note.empty()) {
      accuracy = {{"note", ms.note}};
    }
    maps.push_back({{"id", m.id.counter()},
                    {"largest", m.id == ev.final_map},
                    {"keyframes", m.keyframes},
                    {"anchored_keyframes", m.anchored},
                    {"map_points", m.map_points},
                    {"agents", agent_ids},
                    {"parts", parts},
                    {"ply", MapPlyFile(ev, m.id)},
                    {"accuracy", accuracy}});
  }
  return maps;
}

nlohmann::json AgentsJson(const RunResult& result, const RunEvaluation& ev) {
  nlohmann::json agents = nlohmann::json::array();
  for (size_t i = 0; i < result.agents.size(); ++i) {
    const AgentRunResult& a = result.agents[i];
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
                      {"part_ate_m", StatsJson(sc.part_ate_m)},
                      {"tracking_ms_median", Percentile(a.tracking_ms, 0.5)},
                      {"server_keyframe_ms_median", Percentile(counters.keyframe_ms, 0.5)},
                      {"server_keyframe_ms_p95", Percentile(counters.keyframe_ms, 0.95)},
                      {"trajectory", a.name + "_keyframes.tum"}});
  }
  return agents;
}

// Why maps did or did not fuse, each stage's count in order (as ccm_server's server.json).
nlohmann::json PlaceRecognitionJson(const PlaceMatcherStats& p) {
  nlohmann::json stopped = nlohmann::json::object();
  for (int s = 0; s < kNumVerificationStages; ++s) {
    stopped[VerificationStageName(static_cast<VerificationStage>(s))] = p.fusion_stopped_at[s];
  }
  return {{"queries", p.queries},
          {"fusion_candidates", p.match_candidates},
          {"loop_candidates", p.loop_candidates},
          {"verified", p.verified},
          {"inconsistent", p.inconsistent},
          {"implausible_loops", p.implausible_loops},
          {"accepted_fusions", p.accepted_fusions},
          {"accepted_loops", p.accepted_loops},
          {"fusion_verifications_stopped_at", stopped}};
}

nlohmann::json SummaryJson(const RunResult& result, const RunEvaluation& ev) {
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
    if (e.query.valid()) {  // loops and fusions: which keyframes, and the verified similarity's scale
      events.back()["query"] = {e.query.agent(), e.query.counter()};
      events.back()["candidate"] = {e.candidate.agent(), e.candidate.counter()};
      events.back()["query_from_candidate_scale"] = e.query_from_candidate.scale();
    }
  }
  nlohmann::json gba = nlohmann::json::array();
  for (const auto& [kfs, s] : result.stats.global_ba_seconds) gba.push_back({{"keyframes", kfs}, {"seconds", s}});
  return {{"wall_s", result.wall_s},
          {"final_map", ev.final_map.counter()},
          {"maps", MapsJson(ev)},
          {"fusions", result.stats.fusions},
          {"loops", result.stats.loops},
          {"keyframes_removed_as_redundant", result.stats.keyframes_removed},
          {"place_recognition", PlaceRecognitionJson(result.stats.place)},
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
          {"agents", AgentsJson(result, ev)},
          {"events", events}};
}

}  // namespace

bool WriteRunOutputs(const std::string& dir, const RunResult& result, const RunEvaluation& ev,
                     const MapStackSnapshot& maps, std::string* error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    *error = "cannot create " + dir + ": " + ec.message();
    return false;
  }
  for (const AgentRunResult& a : result.agents) {
    // The largest map under the agent's name alone: the files scripts read before every map
    // was written (empty when the agent is not in that map).
    if (!WriteTum(dir + "/" + a.name + "_keyframes.tum", KeyframesInMap(a.server_keyframes, ev.final_map), error)) return false;
    if (!a.ground_truth.empty() && !WriteTum(dir + "/" + a.name + "_ground_truth.tum", a.ground_truth, error)) {
      return false;
    }
    // The agent's own estimate of its keyframes (its VO, all segments): what the map's copy
    // is compared with ("ATE VO" against "ATE map").
    if (!a.vo_keyframes.empty() && !WriteTum(dir + "/" + a.name + "_vo_keyframes.tum", a.vo_keyframes, error)) {
      return false;
    }
  }
  for (const MapScore& ms : ev.map_scores) {
    for (const AgentInMap& part : ms.agents) {
      const AgentRunResult* a = FindAgent(result, part.id);
      if (!a || part.keyframes == 0) continue;
      const std::string path = dir + "/" + MapTrajectoryFile(ms.summary.id, a->name);
      if (!WriteTum(path, KeyframesInMap(a->server_keyframes, ms.summary.id), error)) return false;
    }
    if (!WriteMapPly(dir + "/" + MapPlyFile(ev, ms.summary.id), maps, ms.summary.id, error)) return false;
  }
  // No map at all (no agent initialized): an empty map.ply, so the file list stays fixed.
  if (ev.map_scores.empty() && !WriteMapPly(dir + "/map.ply", maps, MapId(), error)) return false;
  std::ofstream out(dir + "/summary.json");
  out << SummaryJson(result, ev).dump(2) << "\n";
  if (!out) {
    *error = "cannot write " + dir + "/summary.json";
    return false;
  }
  return WriteMapTopView(dir + "/map_top.png", result, ev, maps, error);
}

}  // namespace ccm::report
