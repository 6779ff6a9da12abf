// Helpers of server_test: the simulator vocabulary, simulations, and an agent's VO run on
// a simulated flight packed into the batches the server receives (no server in the loop).
#pragma once

#include <glog/logging.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "slam_core/io/trajectory.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "slam_core/server/server_backend.h"
#include "slam_core/vo/agent_vo.h"
#include "slam_core/vo/change_packer.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"

namespace ccm::testing {

/// Ceres reports every rejected trial step through glog ("Step failed to evaluate"); the
/// VO's pose optimization produces them by the hundred, which buries test output.
inline const bool kQuietCeres = [] {
  FLAGS_minloglevel = 2;
  return true;
}();

inline std::shared_ptr<const Vocabulary> SimVocabulary() {
  static const std::shared_ptr<const Vocabulary> vocab = [] {
    std::string error;
    auto v = LoadVocabularyFile(CCM_SIM_VOCAB_FILE, &error);
    return v ? std::make_shared<const Vocabulary>(std::move(*v)) : nullptr;
  }();
  return vocab;
}

/// A path in the temp folder unique to this process.
inline std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))).string();
}

inline std::shared_ptr<const sim::Simulation> LoadSim(const std::string& name) {
  std::string error;
  const auto s = sim::LoadScenario(name, &error);
  return s ? std::shared_ptr<const sim::Simulation>(sim::Simulation::Create(*s, &error)) : nullptr;
}

/// One agent's VO on a simulated flight (every `stride`-th frame), packed every
/// `period_frames` frames (with `packing`; default: no send delay, no anchors).
struct VoStream {
  std::vector<AgentBatch> batches;
  std::shared_ptr<Map> final_map;      ///< the VO's local map at the end
  std::vector<KeyframePose> keyframes;  ///< VO keyframe trajectory (own keyframes)
  Trajectory ground_truth;
};

inline VoStream RunVoStream(const std::shared_ptr<const sim::Simulation>& sim, int sim_agent, int64_t first_frame,
                            int64_t frames, int period_frames = 5, VoOptions vo_options = {}, int64_t stride = 1,
                            ChangePackerOptions packing = {}) {
  VoStream out;
  sim::SimFrameSource source(sim, sim_agent, first_frame, stride, frames);
  std::shared_ptr<const CameraModel> camera(MakeCamera(source.intrinsics()));
  static const AckAll acks;
  const AgentId id = static_cast<AgentId>(sim_agent + 1);
  AgentVo vo(id, camera, vo_options, &acks, /*synchronous_mapping=*/true);
  ChangePacker packer(id, packing);
  int64_t n = 0;
  while (auto f = source.Next()) {
    out.ground_truth.push_back({f->stamp_ns, *f->world_from_cam_gt});
    vo.TrackFrame(*f);
    if (++n % period_frames == 0) {
      AgentBatch b = packer.Pack(vo.TakeChanges(), f->stamp_ns);
      if (!b.empty()) out.batches.push_back(std::move(b));
    }
  }
  AgentBatch b = packer.Pack(vo.TakeChanges(), out.ground_truth.empty() ? 0 : out.ground_truth.back().stamp_ns);
  if (!b.empty()) out.batches.push_back(std::move(b));
  out.final_map = vo.map();
  for (const KeyframePose& p : vo.KeyframeTrajectory()) {
    if (p.id.agent() == id) out.keyframes.push_back(p);
  }
  return out;
}

/// 10 s of hall3 agent 0: 200 frames, a few dozen keyframes (computed once per process).
inline const VoStream& Hall3Stream() {
  static const VoStream stream = RunVoStream(LoadSim("hall3"), 0, 0, 200);
  return stream;
}

/// Ground-truth pose at a stamp (exact match; the simulator's stamps are shared).
inline std::optional<SE3> GroundTruthAt(const Trajectory& gt, int64_t stamp_ns) {
  for (const auto& p : gt) {
    if (p.stamp_ns == stamp_ns) return p.world_from_cam;
  }
  return std::nullopt;
}

/// The handlers of `agent` (every segment), as the snapshot holds them.
inline std::vector<AgentHandler> HandlersOf(const MapStackSnapshot& snapshot, AgentId agent) {
  std::vector<AgentHandler> out;
  for (const AgentHandler& h : snapshot.handlers) {
    if (h.agent == agent) out.push_back(h);
  }
  return out;
}

}  // namespace ccm::testing
