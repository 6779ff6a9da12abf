// Runs the agent: the VO on a dataset folder (EuRoC / TUM / KITTI), a live camera / video
// file or a simulated agent, either standalone (no DDS, `ccm_agent --standalone`) or
// connected (the default): then an AgentComm streams the VO's keyframes and points to the
// server and feeds the server's map back into the VO. Writes the per-frame and keyframe
// trajectories (TUM), prints progress and a JSON summary. Owns the VO threads: tracking runs
// on the caller's thread, local mapping on a thread started and joined here; the comm
// thread is AgentComm's.
#pragma once

#include <memory>
#include <string>

#include "agent_runtime/agent_config.h"
#include "runtime_common/dds_session.h"
#include "slam_core/io/frame_source.h"
#include "slam_core/vo/vo_options.h"

namespace ccm::agent {

struct RunOptions {
  std::string dataset;           ///< dataset folder (empty when sim_scenario is set)
  std::string format = "auto";   ///< auto, euroc, tum, kitti
  std::string calibration;       ///< optional calibration YAML override
  std::string sim_scenario;      ///< built-in scenario name or YAML file
  std::string video;             ///< live camera ("0", /dev/video0) or video file; needs calibration
  /// A ROS 2 camera driver's sensor_msgs/Image topic (ros2_camera_source.h); its CameraInfo
  /// gives the calibration unless `calibration` is set.
  std::string ros2_image;
  std::string ros2_camera_info;  ///< empty: beside the image topic (image_transport's rule)
  int ros2_domain = -1;          ///< -1: $ROS_DOMAIN_ID, else 0
  int ros2_queue = 2;            ///< images kept while tracking is busy (older ones are skipped)
  double end_after_s = 0;        ///< live input (camera, ROS 2): end the flight after this much silence (0: never)
  double ros2_info_wait_s = 10;  ///< wait this long for the first CameraInfo
  std::string qos_file;          ///< profiles file of the camera's participant (empty: the default)
  int sim_agent = 0;             ///< agent index within the scenario
  std::string trajectory_out;    ///< per-frame trajectory (TUM); empty: not written
  std::string keyframes_out;     ///< keyframe trajectory (TUM); empty: not written
  std::string ground_truth_out;  ///< ground truth of the processed frames (TUM), if the source has it
  std::string rate = "max";      ///< "max", "realtime" or a speed factor such as "0.5"
  /// Paced input (rate not "max") behaves as a camera that does not wait: a frame whose
  /// successor is already due is skipped and counted (embedded boards, issue 29).
  bool skip_late_frames = false;
  int64_t max_frames = -1;       ///< stop after this many frames (-1: all)
  int agent_id = 1;
  bool no_acks = false;          ///< standalone: behave as if the server never acknowledges
  double progress_period_s = 2.0;
  double drain_s = 30.0;         ///< connected: wait at most this long for the last acks
  int metrics_port = -1;         ///< --metrics: Prometheus endpoint port (-1: off, 0: any free port)
  std::string metrics_bind = "127.0.0.1";
  VoOptions vo;
  /// Bag-of-words vocabulary for relocalization: empty = the built-in one, "none" = brute
  /// force over the local map.
  std::string vocabulary;

  std::string Validate() const;
};

/// The input named by the options. *stop ends a wait for a live camera.
std::unique_ptr<FrameSource> OpenFrameSource(const RunOptions& options, const volatile bool* stop, std::string* error);

/// Standalone when `comm` is null. Runs to the end of the input (or until *stop becomes
/// true). Returns the process exit code: 0 on success, 1 on a runtime failure, 2 on bad
/// input, 3 if keyframes were still unacknowledged after the drain period.
int RunAgent(const RunOptions& options, const AgentConfig* comm, const rt::SessionOptions* session,
             const volatile bool* stop);

}  // namespace ccm::agent
