// Runs the agent VO on one simulated agent (frames rendered in process) and collects the
// estimated and ground-truth trajectories. Shared by vo_test and bench_vo.
#pragma once

#include <memory>
#include <string>

#include "slam_core/eval/evaluator.h"
#include "slam_core/eval/metrics.h"
#include "slam_core/vo/agent_vo.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"

namespace ccm::testing {

struct VoSimRun {
  Trajectory gt, est;
  int64_t frames = 0, frames_after_init = 0, tracked_after_init = 0;
  int64_t first_tracked_index = -1;
  int segments = 1;
  size_t max_keyframes_in_map = 0;
  size_t pending_changes = 0;  ///< changes nobody took, at the end
  AgentVoStats stats;
  double path_length_m = 0.0;
  double ate_rmse_m = -1.0;  ///< Sim(3)-aligned, tracked frames only
  std::string error;
};

inline std::shared_ptr<const sim::Simulation> LoadSimulation(const std::string& scenario, std::string* error) {
  const auto s = sim::LoadScenario(scenario, error);
  if (!s) return nullptr;
  return std::shared_ptr<const sim::Simulation>(sim::Simulation::Create(*s, error));
}

inline VoSimRun RunVoOnSim(const std::shared_ptr<const sim::Simulation>& sim, int agent, int64_t max_frames,
                           const VoOptions& options, const AckSource& acks) {
  VoSimRun run;
  sim::SimFrameSource source(sim, agent, 0, 1, max_frames);
  std::shared_ptr<const CameraModel> camera(MakeCamera(source.intrinsics()));
  AgentVo vo(static_cast<AgentId>(agent + 1), camera, options, &acks, /*synchronous_mapping=*/true);
  bool initialized = false;
  while (auto frame = source.Next()) {
    const TrackingResult r = vo.TrackFrame(*frame);
    ++run.frames;
    run.gt.push_back({frame->stamp_ns, *frame->world_from_cam_gt});
    if (r.world_from_cam) {
      if (!initialized) run.first_tracked_index = run.frames - 1;
      initialized = true;
      run.est.push_back({frame->stamp_ns, *r.world_from_cam});
    }
    if (initialized) {
      ++run.frames_after_init;
      run.tracked_after_init += r.world_from_cam.has_value();
    }
    if (const auto m = vo.map()) run.max_keyframes_in_map = std::max(run.max_keyframes_in_map, m->num_keyframes());
  }
  run.stats = vo.stats();
  run.pending_changes = vo.pending_changes();
  run.est.clear();
  for (const KeyframePose& p : vo.FrameTrajectory()) run.est.push_back({p.stamp_ns, p.world_from_cam});
  run.segments = run.stats.segments;
  std::vector<SE3> gt_poses;
  for (const StampedPose& p : run.gt) gt_poses.push_back(p.world_from_cam);
  run.path_length_m = PathLengthM(gt_poses);
  EvalReport report;
  if (run.est.size() >= 3 && Evaluate({{"agent", run.gt, run.est}}, EvalOptions{}, &report, &run.error)) {
    run.ate_rmse_m = report.agents[0].ate_m.rmse;
  }
  return run;
}

}  // namespace ccm::testing
