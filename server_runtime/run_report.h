// What a run of agents and the server back-end produced (a ccm_replay run, or a live server
// stopping: server_outputs.h), scored and written for EVERY map
// that remains, so an agent that never fused is not invisible: per map, each agent's keyframes, the joint ATE of all its keyframes under one Sim(3)
// alignment (CCM-SLAM's measure) and how well the agents' parts agree in scale; for the
// largest map also the historic per-agent numbers; each agent's standalone VO ATE. Outputs:
// keyframe trajectories per map and agent (TUM), summary.json, PLY per map, one PNG top view
// with a panel per map.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "slam_core/eval/metrics.h"
#include "slam_core/geometry/sim3.h"
#include "slam_core/io/trajectory.h"
#include "slam_core/server/backend_status.h"
#include "slam_core/server/map_stack_snapshot.h"

namespace ccm::report {

struct AgentRunResult {
  std::string name;
  AgentId id = 0;
  int64_t frames = 0, frames_tracked = 0;
  int64_t keyframes_created = 0;
  int segments = 0;
  int64_t relocalizations = 0;        ///< lost, then tracking again in the same segment
  Trajectory ground_truth;            ///< per frame, where the source has it
  Trajectory vo_keyframes;            ///< the agent's own keyframe trajectory (its VO frame)
  std::map<MapId, Trajectory> vo_segments;  ///< the same keyframes by VO segment (each its own frame)
  std::vector<ServerKeyframePose> server_keyframes;  ///< as registered on the server
  /// Its own keyframes >= kRevisitLinkGapNs apart that share >= kRevisitLinkMinPoints
  /// points on the server (the fusion benchmark checks them against ground truth).
  std::vector<RevisitLink> revisit_links;
  std::vector<double> tracking_ms;
};

inline constexpr int64_t kRevisitLinkGapNs = 10'000'000'000;
inline constexpr int kRevisitLinkMinPoints = 15;

struct RunResult {
  std::vector<AgentRunResult> agents;
  std::vector<ServerEvent> events;
  std::vector<MapSummary> maps;
  BackendStats stats;
  double wall_s = 0.0;
  std::string error;  ///< non-empty if the run could not start or a source failed
};

struct AgentScore {
  std::string name;
  AgentId id = 0;
  double path_m = 0.0;              ///< ground-truth path of the frames flown
  size_t server_keyframes = 0;      ///< registered (incl. anchored) in the final map
  size_t vo_keyframes = 0;
  ErrorStats standalone_ate_m;      ///< VO keyframes, own Sim(3) alignment
  ErrorStats collaborative_ate_m;   ///< server keyframes under the joint alignment
  /// Its server keyframes in the final map under their own Sim(3) alignment: what the map
  /// made of this agent's part, apart from how the parts fit together. Compared with
  /// standalone_ate_m it says whether collaborating made the agent's own map better.
  ErrorStats part_ate_m;
};

/// One agent's part of one server map.
struct AgentInMap {
  std::string name;
  AgentId id = 0;
  size_t keyframes = 0;       ///< registered and anchored keyframes of the agent in the map
  /// Of those, the ones held in full (not anchored), as seconds after the agent's first
  /// keyframe in the map: how the map grew over the flight (repeated passes).
  std::vector<double> full_keyframe_s;
  double path_m = 0.0;        ///< ground-truth path between its first and last keyframe there
  ErrorStats ate_m;           ///< under the map's joint alignment
  ErrorStats own_ate_m;       ///< under its own Sim(3) alignment
  /// Scale of this part's own Sim(3) alignment to the ground truth (metres per map unit);
  /// 0 if not scored. Parts of one well-fused map have equal scales.
  double scale_to_gt = 0.0;
};

struct MapScore {
  MapSummary summary;
  std::vector<AgentInMap> agents;   ///< agents with keyframes (or a handler) in the map
  bool scored = false;              ///< ground truth aligned
  ErrorStats joint_ate_m;           ///< every keyframe of the map, one Sim(3) alignment
  double path_m = 0.0;              ///< sum of the agents' path_m
  double joint_ate_percent = 0.0;   ///< RMSE / path_m * 100
  Sim3 gt_from_map;
  /// Largest / smallest scale_to_gt of the map's scored agents: 1 when their parts agree;
  /// 0 with fewer than two scored agents.
  double scale_ratio = 0.0;
  std::string note;                 ///< why it was not scored
};

struct RunEvaluation {
  bool has_ground_truth = false;
  MapId final_map;                  ///< the largest map (all agents' when everything fused)
  size_t maps = 0;
  std::vector<MapScore> map_scores; ///< every map, largest first
  double joint_path_m = 0.0;
  ErrorStats collaborative_ate_m;   ///< every keyframe of the final map, one alignment
  double collaborative_ate_percent = 0.0;  ///< RMSE / joint path * 100
  double mean_standalone_ate_m = 0.0;
  Sim3 gt_from_map;
  std::vector<AgentScore> agents;
  std::string note;                 ///< why something could not be scored
};

RunEvaluation EvaluateRun(const RunResult& result);

/// The run on stdout: per agent its VO and its keyframes in the largest map, every map with
/// its agents and joint ATE, fusions, loops and place recognition's counts.
void PrintRunSummary(const RunResult& result, const RunEvaluation& evaluation);

/// Output file names: the keyframes of `agent` in map `map` ("map<k>_<agent>_keyframes.tum"),
/// and a map's PLY ("map.ply" for the largest map, "map<k>.ply" for the others).
std::string MapTrajectoryFile(MapId map, const std::string& agent);
std::string MapPlyFile(const RunEvaluation& evaluation, MapId map);
/// The keyframes of `kfs` that the server holds in map `map`, as a trajectory.
Trajectory KeyframesInMap(const std::vector<ServerKeyframePose>& kfs, MapId map);

/// Writes into `dir`: map<k>_<agent>_keyframes.tum for every map and agent in it,
/// <agent>_keyframes.tum (largest map, as before maps were listed), <agent>_ground_truth.tum,
/// <agent>_vo_keyframes.tum (the agent's own estimate at the end),
/// summary.json (every map), map.ply / map<k>.ply, map_top.png (a panel per map). The map
/// files are drawn from `maps` (ServerBackend::Snapshot()).
bool WriteRunOutputs(const std::string& dir, const RunResult& result, const RunEvaluation& evaluation,
                     const MapStackSnapshot& maps, std::string* error);

}  // namespace ccm::report
