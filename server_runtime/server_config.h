// ccm_server configuration: defaults, validation and strict YAML loading.
#pragma once

#include <string>

#include "slam_core/server/server_options.h"

namespace ccm::server {
struct Ros2OutputOptions;
}

namespace ccm::server {

struct ServerConfig {
  int domain_id = 0;                 // DDS domain, 0..232
  std::string qos_file;              // empty: $FASTRTPS_DEFAULT_PROFILES_FILE or qos_profiles/default.xml
  std::string security_dir;            // DDS-Security files of this participant (make-pki.sh); empty: no security
  bool insecure = false;                // ignore security_dir (explicit way out of the packaged secure configs)
  std::string participant_profile = "ccm_participant";  // participant profile in qos_file (discovery: ccm_participant_ds_client)
  std::string log_level = "info";
  double publish_rate_hz = 1.0;      // server -> agent messages per agent per second (< agent rate)
  int ack_repeats = 3;               // each ack is repeated in this many messages (they are BEST_EFFORT)
  bool ack_points = false;           // also list processed map points (ccm_agent acts on keyframe acks only)
  int max_agents = 16;
  bool map_sharing = true;           // send each agent the k keyframes most covisible with its reference KF
  int neighbourhood_k = 5;           // that k (CCM-SLAM: 5)
  bool ros2_outputs = false;         // publish paths, poses, tf and the map for ROS 2 tools (docs/ros2.md)
  double ros2_period_s = 1.0;        // paths, poses, tf
  double ros2_cloud_period_s = 5.0;  // the point cloud
  int ros2_max_cloud_points = 50000;
  int ros2_domain = -1;              // the ROS 2 tools' domain; -1: the server's domain_id
  double share_own_keyframes_after_s = 0.0;  // > 0: also an agent's own keyframes this much older than its reference (experimental)
  double revisit_distance_ratio = ServerOptions{}.redundancy.revisit_distance_ratio;  // a keyframe this close to one of an earlier pass leaves as its anchor (0: off)
  int global_ba_max_free_keyframes = ServerOptions{}.optimization.global_ba_max_free_keyframes;  // a loop or fusion in a bigger map: BA of its region (0: whole map)
  double global_ba_min_parallax_deg = ServerOptions{}.optimization.global_ba_min_parallax_deg;  // points seen under less parallax are held in a global BA (0: none)
  bool global_ba_low_parallax_inverse_depth = ServerOptions{}.optimization.global_ba_low_parallax_inverse_depth;  // those points move as inverse depths instead of being held
  double liveliness_timeout_s = 3.0; // no heartbeat for this long: the agent left (logged; its maps stay)
  double agent_slot_release_s = 600.0;  // silent this long: a new agent beyond max_agents takes its slot (0: never)
  std::string vocabulary;            // bag-of-words vocabulary file; empty: the built-in simulator one
  std::string load_map;              // start from this saved map stack (empty: fresh)
  std::string save_map;              // save the map stack here on exit (empty: not saved)
  std::string map_file;              // daemon map: loaded at start if it exists, saved on exit and by autosave
                                     // (load_map / save_map, when given, win for their direction)
  double autosave_s = 20.0;          // save the map stack this often while running (0: only on exit); sized with the agents' B (docs/protocol.md "N+B")
  double status_period_s = 1.0;      // ServerStatus topic period (ccm_ctl status)

  std::string Validate() const;
  /// The ros2_* keys as the ROS 2 publisher's options.
  Ros2OutputOptions Ros2Options() const;
};

bool LoadServerConfig(const std::string& path, ServerConfig* config, std::string* error);

}  // namespace ccm::server
