// `ccm_agent --standalone`: runs the whole agent VO without DDS on a dataset folder
// (EuRoC / TUM / KITTI), a live camera / video file or a simulated agent, writes the per-frame and keyframe
// trajectories (TUM format) and prints progress and timing statistics. Owns the two VO
// threads: tracking runs on the caller's thread, local mapping on a thread started and
// joined by Run().
#pragma once

#include <string>

#include "slam_core/vo/vo_options.h"

namespace ccm::agent {

struct StandaloneOptions {
  std::string dataset;           ///< dataset folder (empty when sim_scenario is set)
  std::string format = "auto";   ///< auto, euroc, tum, kitti
  std::string calibration;       ///< optional calibration YAML override
  std::string sim_scenario;      ///< built-in scenario name or YAML file
  std::string video;             ///< live camera ("0", /dev/video0) or video file; needs calibration
  int sim_agent = 0;             ///< agent index within the scenario
  std::string trajectory_out;    ///< per-frame trajectory (TUM); empty: not written
  std::string keyframes_out;     ///< keyframe trajectory (TUM); empty: not written
  std::string ground_truth_out;  ///< ground truth of the processed frames (TUM), if the source has it
  std::string rate = "max";      ///< "max", "realtime" or a speed factor such as "0.5"
  int64_t max_frames = -1;       ///< stop after this many frames (-1: all)
  int agent_id = 1;
  bool no_acks = false;           ///< behave as if the server never acknowledges (bounded-map check)
  double progress_period_s = 2.0;
  VoOptions vo;

  std::string Validate() const;
};

/// Runs to the end of the input (or until *stop becomes true). Returns the process exit
/// code: 0 on success, 1 on a runtime failure, 2 on bad input; prints a JSON summary.
int RunStandalone(const StandaloneOptions& options, const volatile bool* stop);

}  // namespace ccm::agent
