// Trajectory evaluation of one or several agents: association, alignment, ATE and RPE.
// Each agent is evaluated with its own alignment, and all agents together with ONE alignment
// computed over the associated pairs of all agents (the agents' estimates must be expressed in
// one map frame): this "joint" ATE is the collaborative RMSE CCM-SLAM reports.
// Synchronous, no I/O: ccm_eval (tools/eval) reads files and prints.
#pragma once

#include <string>
#include <vector>

#include "slam_core/eval/alignment.h"
#include "slam_core/eval/association.h"
#include "slam_core/eval/metrics.h"
#include "slam_core/io/trajectory.h"

namespace ccm {

struct EvalOptions {
  AlignmentType alignment = AlignmentType::kSim3;  ///< sim3 for monocular, se3 for metric
  /// Align on the first N associated pairs of each agent only (evo --n_to_align); -1: all.
  int align_first_n = -1;
  AssociationOptions association;
  RpeOptions rpe;
  /// > 0: each agent's scale drift over windows of this many metres of path (0: off).
  double scale_window_m = 0.0;
  bool Validate(std::string* error) const;
};

struct AgentInput {
  std::string name;
  Trajectory gt;
  Trajectory est;
};

struct AgentResult {
  std::string name;
  size_t gt_poses = 0, est_poses = 0, matched = 0;
  std::vector<SE3> gt_matched;   ///< associated ground-truth poses, in association order
  std::vector<SE3> est_matched;  ///< associated estimated poses, unaligned
  std::vector<int64_t> stamps_ns;  ///< ground-truth stamps of the pairs
  Sim3 gt_from_est;                ///< this agent's own alignment
  std::vector<double> ate_errors_m;
  ErrorStats ate_m;  ///< under the agent's own alignment
  RpeResult rpe;     ///< on the estimate under its own alignment
  ScaleDrift scale_drift;  ///< under its own alignment (window scales around 1); if asked
  ErrorStats ate_joint_m;  ///< under the joint alignment
};

struct JointResult {
  size_t matched = 0;
  Sim3 gt_from_est;  ///< one alignment for all agents
  ErrorStats ate_m;
  ErrorStats rpe_translation_m;  ///< RPE pairs of all agents under the joint alignment
  ErrorStats rpe_rotation_deg;
};

struct EvalReport {
  std::vector<AgentResult> agents;
  JointResult joint;
};

/// Applies a similarity to every pose (positions mapped, orientations rotated).
std::vector<SE3> ApplyAlignment(const Sim3& gt_from_est, const std::vector<SE3>& est);

/// False with a message (which agent, why) if an agent has no associated poses or the
/// alignment is degenerate.
bool Evaluate(const std::vector<AgentInput>& agents, const EvalOptions& options,
              EvalReport* report, std::string* error);

}  // namespace ccm
