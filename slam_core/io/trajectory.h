// A camera trajectory: poses world_from_cam with timestamps, in file or time order.
// Produced by the trajectory readers and the SLAM front/back end, consumed by ccm_eval.
#pragma once

#include <cstdint>
#include <vector>

#include "slam_core/geometry/se3.h"

namespace ccm {

struct StampedPose {
  int64_t stamp_ns = 0;
  SE3 world_from_cam;
};

using Trajectory = std::vector<StampedPose>;

/// Seconds (as in TUM files) to integer nanoseconds, rounded to the nearest ns.
int64_t SecondsToNs(double stamp_s);
inline double NsToSeconds(int64_t stamp_ns) { return static_cast<double>(stamp_ns) * 1e-9; }

}  // namespace ccm
