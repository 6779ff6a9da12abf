// Scores and writes what a replay produced: collaborative ATE of every keyframe in the final
// map's frame (one Sim(3) alignment over all agents, CCM-SLAM's measure) next to each agent's
// standalone VO ATE, and the output folder: per-agent keyframe trajectories (TUM) in the
// final map's frame, summary.json, the fused map as PLY and a PNG top view.
#pragma once

#include <string>
#include <vector>

#include "slam_core/eval/metrics.h"
#include "slam_core/geometry/sim3.h"
#include "tools/replay/replay_session.h"

namespace ccm::replay {

struct AgentScore {
  std::string name;
  AgentId id = 0;
  double path_m = 0.0;              ///< ground-truth path of the frames flown
  size_t server_keyframes = 0;      ///< registered (incl. anchored) in the final map
  size_t vo_keyframes = 0;
  ErrorStats standalone_ate_m;      ///< VO keyframes, own Sim(3) alignment
  ErrorStats collaborative_ate_m;   ///< server keyframes under the joint alignment
};

struct ReplayEvaluation {
  bool has_ground_truth = false;
  MapId final_map;                  ///< the largest map (all agents' when everything fused)
  size_t maps = 0;
  double joint_path_m = 0.0;
  ErrorStats collaborative_ate_m;   ///< every keyframe of the final map, one alignment
  double collaborative_ate_percent = 0.0;  ///< RMSE / joint path * 100
  double mean_standalone_ate_m = 0.0;
  Sim3 gt_from_map;
  std::vector<AgentScore> agents;
  std::string note;                 ///< why something could not be scored
};

ReplayEvaluation EvaluateReplay(const ReplayResult& result);

/// Writes agent<i>_keyframes.tum (final map frame), summary.json, map.ply, map_top.png.
bool WriteReplayOutputs(const std::string& dir, const ReplayResult& result, const ReplayEvaluation& evaluation,
                        const ServerBackend& backend, std::string* error);

}  // namespace ccm::replay
