#include "tests/sim/sim_frame_source.h"

#include <algorithm>

namespace ccm::sim {

SimFrameSource::SimFrameSource(std::shared_ptr<const Simulation> sim, int agent, std::int64_t first_index,
                               std::int64_t stride, std::int64_t max_frames)
    : sim_(std::move(sim)), agent_(agent), first_(first_index), stride_(std::max<std::int64_t>(1, stride)) {
  if (sim_) camera_ = sim_->scenario().camera;
  if (!sim_ || agent_ < 0 || agent_ >= sim_->num_agents()) {
    count_ = 0;
    error_ = "no agent " + std::to_string(agent_) + " in the simulation";
    return;
  }
  const std::int64_t total = sim_->NumFrames(agent_);
  count_ = first_ >= total ? 0 : (total - first_ + stride_ - 1) / stride_;
  if (max_frames >= 0) count_ = std::min(count_, max_frames);
}

std::optional<Frame> SimFrameSource::Next() {
  if (next_ >= count_) return std::nullopt;
  const std::int64_t index = first_ + next_ * stride_;
  ++next_;
  Frame f;
  f.stamp_ns = sim_->StampNs(agent_, index);
  f.image = sim_->RenderFrame(agent_, index);
  f.world_from_cam_gt = sim_->WorldFromCam(agent_, index);
  f.source_name = "sim:" + sim_->agent_name(agent_) + ":" + std::to_string(index);
  return f;
}

}  // namespace ccm::sim
