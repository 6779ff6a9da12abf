// ccm::FrameSource that renders one simulated agent in process: the same images the
// EuRoC writer stores, with the exact world_from_cam pose attached. Lets demos and tests
// fly a scenario without writing thousands of PNGs. One consumer thread owns it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "slam_core/io/frame_source.h"
#include "tests/sim/simulation.h"

namespace ccm::sim {

class SimFrameSource : public FrameSource {
 public:
  /// Frames first_index, first_index + stride, ... of `agent` (at most max_frames if >= 0).
  /// An invalid agent gives an empty source whose error() says so.
  SimFrameSource(std::shared_ptr<const Simulation> sim, int agent, std::int64_t first_index = 0,
                 std::int64_t stride = 1, std::int64_t max_frames = -1);

  std::optional<Frame> Next() override;
  const CameraIntrinsics& intrinsics() const override { return camera_; }
  std::int64_t size() const override { return count_; }
  const std::string& error() const override { return error_; }

 private:
  std::shared_ptr<const Simulation> sim_;
  CameraIntrinsics camera_;
  int agent_;
  std::int64_t first_, stride_, count_, next_ = 0;
  std::string error_;
};

}  // namespace ccm::sim
