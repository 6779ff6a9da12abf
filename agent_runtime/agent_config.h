// ccm_agent configuration: defaults, validation and strict YAML loading. The command line
// overrides single fields after the file is loaded.
#pragma once

#include <string>

#include "slam_core/map/near_duplicate.h"
#include "slam_core/vo/change_packer.h"
#include "slam_core/vo/vo_options.h"

namespace ccm::agent {

struct AgentConfig {
  int agent_id = 1;                    // 1..65535, unique in the team
  int domain_id = 0;                   // DDS domain, 0..232
  std::string qos_file;                // empty: $FASTRTPS_DEFAULT_PROFILES_FILE or qos_profiles/default.xml
  std::string security_dir;            // DDS-Security files of this participant (make-pki.sh); empty: no security
  bool insecure = false;                // ignore security_dir (explicit way out of the packaged secure configs)
  std::string participant_profile = "ccm_participant";  // participant profile in qos_file (discovery: ccm_participant_ds_client)
  std::string log_level = "info";
  double publish_rate_hz = 4.0;        // agent -> server messages per second (CCM-SLAM: 2-5 Hz)
  int max_bytes_per_cycle = 600000;    // new data written per publish cycle; more waits (backlog split)
  int point_updates_per_sample = 30;   // map point updates per BEST_EFFORT sample: 30 x ~40 B fit one 1400 B datagram (wifi.xml), so a lost datagram loses 30 updates, not a fragmented batch
  bool map_sharing = true;             // integrate the keyframes the server sends back
  double new_keyframe_delay_s = 1.5;   // a new KF leaves once this old (data time): KFs culled sooner never cost uplink
  // A KF within distance_ratio x scene depth and max_angle_deg of one the server has in full,
  // whose points keep >= 2 such observers, leaves as a pose anchor only (the server's
  // near-duplicate rule, applied before sending). distance_ratio 0: every KF in full.
  NearDuplicateRule anchor_duplicates;
  double status_rate_hz = 1.0;         // AgentStatus heartbeat rate
  double resend_holdoff_s = 3.0;       // KF i acked, i-1 not: resend i-1 only if sent this long ago (>= the server's ack_repeats / publish_rate_hz: its ack may still come in a repeat)
  double ack_timeout_s = 5.0;          // resend a KF unacknowledged for this long
  int max_keyframes = 50;              // N: local map size (CCM-SLAM default)
  int buffer_keyframes = 50;           // B: extra unacknowledged KFs kept (paper: B = N)
  std::string vocabulary;              // bag-of-words vocabulary for relocalization; empty: built-in, "none": brute force
  VoOptions vo;                        // `vo:` section (docs/configuration.md); N and B above win
  // One file per robot (deploy/config/agent-onboard.yaml): its camera and calibration live
  // here too, so `ccm_agent -c robot.yaml` (the systemd unit) needs no other argument. The
  // server's address is in the QoS file (initial peers or discovery server).
  std::string camera;                  // live camera ("0", /dev/video0) or video file; --video/--dataset/--sim win
  std::string calibration;             // camera calibration YAML (needed with camera); --calibration wins
  std::string ros2_image;              // a ROS 2 camera driver's Image topic instead of `camera` (docs/ros2.md)
  std::string ros2_camera_info;        // its CameraInfo topic; empty: beside the image topic
  int ros2_domain = -1;                // the camera's ROS 2 domain; -1: $ROS_DOMAIN_ID, else 0
  int opencv_threads = 1;              // OpenCV worker threads (image pyramids); 0: OpenCV's default (all cores)
  bool skip_late_frames = false;       // recorded input at --rate realtime behaves as a camera: late frames skipped

  /// The VO options the agent runs with: the `vo:` section with N and B applied.
  VoOptions EffectiveVo() const;
  /// How the agent's ChangePacker packs (keyframe delay, pose anchors).
  ChangePackerOptions Packing() const {
    ChangePackerOptions o;
    o.new_keyframe_delay_s = new_keyframe_delay_s;
    o.anchor_duplicates = anchor_duplicates;
    return o;
  }

  /// Empty when valid, otherwise the first problem found.
  std::string Validate() const;
};

/// New data written per publish cycle: `max_bytes_per_cycle`, but never more than
/// kShareOfCap of what a writer capped at `cap_bytes_per_s` (0: uncapped) sends in one
/// cycle. Fast DDS 2.9.1's throughput controller starves a writer that is offered more than
/// its cap instead of sending at the cap (docs/qos-tuning.md), and repairs of lost
/// fragments take their share of the cap too. At least 1000 bytes.
inline constexpr double kShareOfCap = 0.75;
/// The IDL's bound on map point updates per MapPointUpdateBatch (kMaxPointUpdatesPerBatch;
/// agent_comm.cc checks that they agree).
inline constexpr int kMaxPointUpdatesPerSample = 4096;
int NewDataBytesPerCycle(int max_bytes_per_cycle, double cap_bytes_per_s, double publish_rate_hz);

/// Loads `path` over the defaults in *config. False with a message naming file and key on
/// a missing file, a syntax error, an unknown key, a wrong type or an invalid value.
bool LoadAgentConfig(const std::string& path, AgentConfig* config, std::string* error);

}  // namespace ccm::agent
