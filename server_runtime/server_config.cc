#include "server_runtime/server_config.h"

#include "runtime_common/yaml_config.h"
#include "server_runtime/ros2_outputs.h"

namespace ccm::server {

std::string ServerConfig::Validate() const {
  if (domain_id < 0 || domain_id > 232) return "domain_id must be in 0..232";
  if (!(publish_rate_hz > 0.0 && publish_rate_hz <= 50.0)) return "publish_rate_hz must be in (0, 50]";
  if (ack_repeats < 1 || ack_repeats > 20) return "ack_repeats must be in 1..20";
  if (max_agents < 1 || max_agents > 64) return "max_agents must be in 1..64 (see resource limits in the QoS file)";
  if (neighbourhood_k < 0 || neighbourhood_k > 16) return "neighbourhood_k must be in 0..16 (idl kMaxKeyframesPerServerMsg)";
  if (!(share_own_keyframes_after_s >= 0.0)) return "share_own_keyframes_after_s must be >= 0 (0: off)";
  if (!(revisit_distance_ratio >= 0.0 && revisit_distance_ratio < 1.0)) {
    return "revisit_distance_ratio must be in [0, 1) (0: off)";
  }
  if (global_ba_max_free_keyframes < 0) return "global_ba_max_free_keyframes must be >= 0 (0: the whole map)";
  if (!(global_ba_min_parallax_deg >= 0.0 && global_ba_min_parallax_deg < 90.0)) {
    return "global_ba_min_parallax_deg must be in [0, 90) degrees (0: no point held)";
  }
  if (!(liveliness_timeout_s > 0.0)) return "liveliness_timeout_s must be > 0";
  if (!(agent_slot_release_s == 0.0 || agent_slot_release_s >= liveliness_timeout_s)) {
    return "agent_slot_release_s must be 0 (never) or >= liveliness_timeout_s";
  }
  if (participant_profile.empty()) return "participant_profile must not be empty";
  if (!(autosave_s == 0.0 || autosave_s >= 1.0)) return "autosave_s must be 0 (off) or >= 1";
  if (!(status_period_s >= 0.1 && status_period_s <= 60.0)) return "status_period_s must be in [0.1, 60]";
  if (ros2_outputs) return Ros2Options().Validate();
  return {};
}

Ros2OutputOptions ServerConfig::Ros2Options() const {
  Ros2OutputOptions o;
  o.period_s = ros2_period_s;
  o.cloud_period_s = ros2_cloud_period_s;
  o.max_cloud_points = static_cast<size_t>(std::max(0, ros2_max_cloud_points));
  o.domain_id = ros2_domain;
  return o;
}

bool LoadServerConfig(const std::string& path, ServerConfig* config, std::string* error) {
  auto node = rt::YamlReader::LoadFile(path, error);
  if (!node) return false;
  rt::YamlReader r(*node, path);
  r.Get("domain_id", &config->domain_id);
  r.Get("qos_file", &config->qos_file);
  r.Get("security_dir", &config->security_dir);
  r.Get("insecure", &config->insecure);
  r.Get("participant_profile", &config->participant_profile);
  r.Get("log_level", &config->log_level);
  r.Get("publish_rate_hz", &config->publish_rate_hz);
  r.Get("ack_repeats", &config->ack_repeats);
  r.Get("ack_points", &config->ack_points);
  r.Get("max_agents", &config->max_agents);
  r.Get("map_sharing", &config->map_sharing);
  r.Get("neighbourhood_k", &config->neighbourhood_k);
  r.Get("ros2_outputs", &config->ros2_outputs);
  r.Get("ros2_period_s", &config->ros2_period_s);
  r.Get("ros2_cloud_period_s", &config->ros2_cloud_period_s);
  r.Get("ros2_max_cloud_points", &config->ros2_max_cloud_points);
  r.Get("ros2_domain", &config->ros2_domain);
  r.Get("share_own_keyframes_after_s", &config->share_own_keyframes_after_s);
  r.Get("revisit_distance_ratio", &config->revisit_distance_ratio);
  r.Get("global_ba_max_free_keyframes", &config->global_ba_max_free_keyframes);
  r.Get("global_ba_min_parallax_deg", &config->global_ba_min_parallax_deg);
  r.Get("global_ba_low_parallax_inverse_depth", &config->global_ba_low_parallax_inverse_depth);
  r.Get("liveliness_timeout_s", &config->liveliness_timeout_s);
  r.Get("agent_slot_release_s", &config->agent_slot_release_s);
  r.Get("vocabulary", &config->vocabulary);
  r.Get("load_map", &config->load_map);
  r.Get("save_map", &config->save_map);
  r.Get("map_file", &config->map_file);
  r.Get("autosave_s", &config->autosave_s);
  r.Get("status_period_s", &config->status_period_s);
  r.RejectUnknownKeys();
  if (!r.ok()) {
    *error = r.error();
    return false;
  }
  if (const std::string problem = config->Validate(); !problem.empty()) {
    *error = path + ": " + problem;
    return false;
  }
  return true;
}

}  // namespace ccm::server
