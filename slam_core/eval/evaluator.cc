#include "slam_core/eval/evaluator.h"

#include <algorithm>

namespace ccm {

bool EvalOptions::Validate(std::string* error) const {
  if (align_first_n == 0 || align_first_n < -1) {
    *error = "align_first_n must be -1 (all) or >= 1";
    return false;
  }
  if (!(scale_window_m >= 0.0)) {
    *error = "scale_window_m must be >= 0";
    return false;
  }
  return association.Validate(error) && rpe.Validate(error);
}

std::vector<SE3> ApplyAlignment(const Sim3& gt_from_est, const std::vector<SE3>& est) {
  std::vector<SE3> aligned;
  aligned.reserve(est.size());
  for (const SE3& pose : est) aligned.push_back(gt_from_est.TransformPose(pose));
  return aligned;
}

namespace {

// Appends the positions of the first `first_n` (-1: all) pairs of an agent.
void AppendPositions(const AgentResult& agent, int first_n, std::vector<Eigen::Vector3d>* est,
                     std::vector<Eigen::Vector3d>* gt) {
  const size_t n = first_n < 0 ? agent.matched
                               : std::min(agent.matched, static_cast<size_t>(first_n));
  for (size_t i = 0; i < n; ++i) {
    est->push_back(agent.est_matched[i].translation());
    gt->push_back(agent.gt_matched[i].translation());
  }
}

bool Align(const std::vector<const AgentResult*>& agents, const EvalOptions& options,
           Sim3* gt_from_est, std::string* error) {
  *gt_from_est = Sim3();
  if (options.alignment == AlignmentType::kNone) return true;
  std::vector<Eigen::Vector3d> est, gt;
  for (const AgentResult* agent : agents) AppendPositions(*agent, options.align_first_n, &est, &gt);
  const std::optional<Sim3> sim3 =
      UmeyamaAlignment(est, gt, options.alignment == AlignmentType::kSim3, error);
  if (!sim3) return false;
  *gt_from_est = *sim3;
  return true;
}

bool Associate(const AgentInput& input, const AssociationOptions& options, AgentResult* agent,
               std::string* error) {
  agent->name = input.name;
  agent->gt_poses = input.gt.size();
  agent->est_poses = input.est.size();
  for (const AssociatedPair& pair : AssociateByStamp(input.gt, input.est, options)) {
    agent->gt_matched.push_back(input.gt[pair.gt_index].world_from_cam);
    agent->est_matched.push_back(input.est[pair.est_index].world_from_cam);
    agent->stamps_ns.push_back(input.gt[pair.gt_index].stamp_ns);
  }
  agent->matched = agent->gt_matched.size();
  if (agent->matched == 0) {
    *error = "agent '" + input.name + "': no estimated pose is within " +
             std::to_string(options.max_dt_s) + " s of a ground-truth pose (check time units/offset)";
    return false;
  }
  return true;
}

}  // namespace

bool Evaluate(const std::vector<AgentInput>& agents, const EvalOptions& options,
              EvalReport* report, std::string* error) {
  *report = EvalReport();
  if (!options.Validate(error)) return false;
  if (agents.empty()) {
    *error = "no trajectories to evaluate";
    return false;
  }
  std::vector<const AgentResult*> all;
  for (const AgentInput& input : agents) {
    AgentResult agent;
    if (!Associate(input, options.association, &agent, error)) return false;
    report->agents.push_back(std::move(agent));
  }
  std::vector<double> joint_errors, joint_rpe_t, joint_rpe_r;
  for (AgentResult& agent : report->agents) {
    all.push_back(&agent);
    if (!Align({&agent}, options, &agent.gt_from_est, error)) {
      *error = "agent '" + agent.name + "': " + *error;
      return false;
    }
    const std::vector<SE3> aligned = ApplyAlignment(agent.gt_from_est, agent.est_matched);
    agent.ate_errors_m = AbsoluteTranslationErrors(agent.gt_matched, aligned);
    agent.ate_m = ComputeStats(agent.ate_errors_m);
    agent.rpe = ComputeRpe(agent.gt_matched, aligned, options.rpe);
    if (options.scale_window_m > 0.0) agent.scale_drift = ComputeScaleDrift(agent.gt_matched, aligned, options.scale_window_m);
  }
  JointResult& joint = report->joint;
  if (!Align(all, options, &joint.gt_from_est, error)) {
    *error = "joint alignment: " + *error;
    return false;
  }
  for (AgentResult& agent : report->agents) {
    const std::vector<SE3> aligned = ApplyAlignment(joint.gt_from_est, agent.est_matched);
    const std::vector<double> errors = AbsoluteTranslationErrors(agent.gt_matched, aligned);
    agent.ate_joint_m = ComputeStats(errors);
    joint_errors.insert(joint_errors.end(), errors.begin(), errors.end());
    const RpeResult rpe = ComputeRpe(agent.gt_matched, aligned, options.rpe);
    joint_rpe_t.insert(joint_rpe_t.end(), rpe.translation_errors_m.begin(),
                       rpe.translation_errors_m.end());
    joint_rpe_r.insert(joint_rpe_r.end(), rpe.rotation_errors_deg.begin(),
                       rpe.rotation_errors_deg.end());
    joint.matched += agent.matched;
  }
  joint.ate_m = ComputeStats(joint_errors);
  joint.rpe_translation_m = ComputeStats(joint_rpe_t);
  joint.rpe_rotation_deg = ComputeStats(joint_rpe_r);
  return true;
}

}  // namespace ccm
