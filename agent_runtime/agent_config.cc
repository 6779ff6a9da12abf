#include "agent_runtime/agent_config.h"

#include <algorithm>

#include "runtime_common/yaml_config.h"

namespace ccm::agent {

VoOptions AgentConfig::EffectiveVo() const {
  VoOptions v = vo;
  v.bound.max_keyframes = max_keyframes;
  v.bound.max_unacked_buffer = buffer_keyframes;
  return v;
}

int NewDataBytesPerCycle(int max_bytes_per_cycle, double cap_bytes_per_s, double publish_rate_hz) {
  if (!(cap_bytes_per_s > 0.0) || !(publish_rate_hz > 0.0)) return max_bytes_per_cycle;
  const double share = kShareOfCap * cap_bytes_per_s / publish_rate_hz;
  return std::max(1000, std::min(max_bytes_per_cycle, static_cast<int>(share)));
}

std::string AgentConfig::Validate() const {
  if (agent_id < 1 || agent_id > 65535) return "agent_id must be in 1..65535";
  if (domain_id < 0 || domain_id > 232) return "domain_id must be in 0..232";
  if (!(publish_rate_hz > 0.0 && publish_rate_hz <= 50.0)) return "publish_rate_hz must be in (0, 50]";
  if (max_bytes_per_cycle < 1000) return "max_bytes_per_cycle must be >= 1000";
  if (point_updates_per_sample < 1 || point_updates_per_sample > kMaxPointUpdatesPerSample) {
    return "point_updates_per_sample must be in 1.." + std::to_string(kMaxPointUpdatesPerSample);
  }
  if (!(status_rate_hz > 0.0 && status_rate_hz <= 50.0)) return "status_rate_hz must be in (0, 50]";
  if (!(resend_holdoff_s >= 0.0)) return "resend_holdoff_s must be >= 0";
  if (!(ack_timeout_s > 0.0)) return "ack_timeout_s must be > 0";
  if (!(new_keyframe_delay_s >= 0.0 && new_keyframe_delay_s <= 30.0)) return "new_keyframe_delay_s must be in [0, 30]";
  if (const std::string e = anchor_duplicates.Validate(); !e.empty()) return "anchor_duplicate_" + e;
  if (max_keyframes < 2) return "max_keyframes (N) must be >= 2";
  if (buffer_keyframes < 0) return "buffer_keyframes (B) must be >= 0";
  if (participant_profile.empty()) return "participant_profile must not be empty";
  if (opencv_threads < 0 || opencv_threads > 64) return "opencv_threads must be in 0..64";
  if (!camera.empty() && !ros2_image.empty()) return "give camera or ros2_image, not both";
  if (ros2_image.empty() && !ros2_camera_info.empty()) return "ros2_camera_info needs ros2_image";
  if (ros2_domain < -1 || ros2_domain > 232) return "ros2_domain must be in 0..232 (-1: $ROS_DOMAIN_ID)";
  if (const std::string e = vo.Validate(); !e.empty()) return "vo: " + e;
  return {};
}

namespace {

// The tunables an operator is expected to touch (docs/vo.md explains each).
bool ReadVoOptions(const YAML::Node& node, const std::string& context, VoOptions* vo, std::string* error) {
  rt::YamlReader r(node, context);
  r.Get("features", &vo->orb.num_features);
  r.Get("pyramid_levels", &vo->orb.num_levels);
  r.Get("init_features", &vo->init_num_features);
  r.Get("fast_threshold", &vo->orb.ini_fast_threshold);
  r.Get("fast_min_threshold", &vo->orb.min_fast_threshold);
  r.Get("fast_max_threshold", &vo->orb.max_fast_threshold);
  r.Get("fast_adapt_high_ratio", &vo->orb.adapt_high_ratio);
  r.Get("fast_adapt_low_ratio", &vo->orb.adapt_low_ratio);
  r.Get("init_min_homography_ratio", &vo->init_min_homography_ratio);
  r.Get("init_count_distant_points", &vo->init_count_distant_points);
  r.Get("init_min_parallax_deg", &vo->init_min_parallax_deg);
  r.Get("init_fallback_homography_ratio", &vo->init_fallback_homography_ratio);
  r.Get("init_min_rotation_residual_deg", &vo->init_min_rotation_residual_deg);
  r.Get("init_min_motion_cost_gap", &vo->init_min_motion_cost_gap);
  r.Get("init_max_ambiguous_attempts", &vo->init_max_ambiguous_attempts);
  r.Get("init_homography_min_parallax_deg", &vo->init_homography_min_parallax_deg);
  r.Get("weak_inlier_drop_ratio", &vo->weak_inlier_drop_ratio);
  std::string kf_reference;
  r.Get("kf_reference", &kf_reference);
  if (!kf_reference.empty() && !ParseKeyframeReference(kf_reference, &vo->kf_reference)) {
    r.Fail("kf_reference", "must be last, most_covisible or either (got '" + kf_reference + "')");
  }
  r.Get("kf_min_frames", &vo->keyframe.min_frames);
  r.Get("kf_min_interval_s", &vo->keyframe.min_interval_s);
  r.Get("kf_max_frames", &vo->keyframe.max_frames);
  r.Get("kf_tracked_ratio", &vo->keyframe.tracked_ratio);
  r.Get("kf_urgent_ratio", &vo->keyframe.urgent_ratio);
  r.Get("kf_urgent_inliers", &vo->keyframe.urgent_inliers);
  r.Get("kf_inlier_drop_ratio", &vo->keyframe.inlier_drop_ratio);
  r.Get("kf_turn_fov_share", &vo->keyframe.turn_fov_share);
  r.Get("kf_coverage_ratio", &vo->keyframe.coverage_ratio);
  r.Get("kf_baseline_depth_ratio", &vo->keyframe.baseline_depth_ratio);
  r.Get("kf_max_interval_s", &vo->keyframe.max_interval_s);
  r.Get("local_ba_window", &vo->local_ba_window);
  r.Get("triangulation_neighbours", &vo->triangulation_neighbours);
  r.Get("triangulate_widest_baseline_first", &vo->triangulate_widest_baseline_first);
  r.Get("min_triangulation_parallax_deg", &vo->min_triangulation_parallax_deg);
  r.Get("min_baseline_depth_ratio", &vo->min_baseline_depth_ratio);
  r.Get("local_ba_max_fixed", &vo->local_ba_max_fixed);
  r.Get("triangulation_parallax_sigmas", &vo->triangulation_parallax_sigmas);
  r.Get("lost_frames_before_new_segment", &vo->lost_frames_before_new_segment);
  r.Get("record_frame_trajectory", &vo->record_frame_trajectory);
  r.RejectUnknownKeys();
  if (!r.ok()) *error = r.error();
  return r.ok();
}

}  // namespace

bool LoadAgentConfig(const std::string& path, AgentConfig* config, std::string* error) {
  auto node = rt::YamlReader::LoadFile(path, error);
  if (!node) return false;
  rt::YamlReader r(*node, path);
  r.Get("agent_id", &config->agent_id);
  r.Get("domain_id", &config->domain_id);
  r.Get("qos_file", &config->qos_file);
  r.Get("security_dir", &config->security_dir);
  r.Get("insecure", &config->insecure);
  r.Get("participant_profile", &config->participant_profile);
  r.Get("log_level", &config->log_level);
  r.Get("publish_rate_hz", &config->publish_rate_hz);
  r.Get("max_bytes_per_cycle", &config->max_bytes_per_cycle);
  r.Get("point_updates_per_sample", &config->point_updates_per_sample);
  r.Get("map_sharing", &config->map_sharing);
  r.Get("status_rate_hz", &config->status_rate_hz);
  r.Get("resend_holdoff_s", &config->resend_holdoff_s);
  r.Get("ack_timeout_s", &config->ack_timeout_s);
  r.Get("new_keyframe_delay_s", &config->new_keyframe_delay_s);
  r.Get("anchor_duplicate_distance_ratio", &config->anchor_duplicates.distance_ratio);
  r.Get("anchor_duplicate_max_angle_deg", &config->anchor_duplicates.max_angle_deg);
  r.Get("max_keyframes", &config->max_keyframes);
  r.Get("buffer_keyframes", &config->buffer_keyframes);
  r.Get("vocabulary", &config->vocabulary);
  r.Get("camera", &config->camera);
  r.Get("calibration", &config->calibration);
  r.Get("ros2_image", &config->ros2_image);
  r.Get("ros2_camera_info", &config->ros2_camera_info);
  r.Get("ros2_domain", &config->ros2_domain);
  r.Get("opencv_threads", &config->opencv_threads);
  r.Get("skip_late_frames", &config->skip_late_frames);
  if (const YAML::Node vo_node = r.Child("vo"); vo_node && r.ok()) {
    if (!vo_node.IsMap()) {
      r.Fail("vo", "must be a mapping of VO options");
    } else if (!ReadVoOptions(vo_node, path + ": vo", &config->vo, error)) {
      return false;
    }
  }
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

}  // namespace ccm::agent
