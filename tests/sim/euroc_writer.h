// Writes one simulated agent as an EuRoC ASL folder:
//   <out>/<agent>/mav0/cam0/data/<stamp_ns>.png, cam0/data.csv, cam0/sensor.yaml,
//   <out>/<agent>/mav0/state_groundtruth_estimate0/data.csv (camera pose, T_BS = I).
// Tools only (the CLI and tests); slam_core never writes files.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "slam_core/geometry/camera.h"
#include "tests/sim/simulation.h"

namespace ccm::sim {

/// Called after each written frame with (frames done, frames total).
using ProgressFn = std::function<void(std::int64_t, std::int64_t)>;

/// Renders and writes frames [0, n) of `agent` (n = all, or max_frames if >= 0) under
/// out_dir/<agent name>. Returns an empty string on success, else what failed.
std::string WriteEurocAgent(const Simulation& sim, int agent, const std::string& out_dir,
                            std::int64_t max_frames = -1, const ProgressFn& progress = {});

/// EuRoC cam0 sensor.yaml text for a camera (T_BS identity).
std::string EurocSensorYaml(const CameraIntrinsics& camera, double rate_hz);

/// EuRoC ground-truth CSV header line (without newline).
const char* EurocGroundTruthHeader();

}  // namespace ccm::sim
