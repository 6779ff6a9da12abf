#include "slam_core/server/server_options.h"

namespace ccm {

std::string RegistrationOptions::Validate() const {
  if (!(scale_kappa > 0.0 && scale_kappa <= 1.0)) return "registration.scale_kappa must be in (0, 1]";
  if (!(scale_min_baseline_depth_ratio >= 0.0)) return "registration.scale_min_baseline_depth_ratio must be >= 0";
  if (!(scale_max_step > 1.0)) return "registration.scale_max_step must be > 1";
  if (refine_min_inliers < 3) return "registration.refine_min_inliers must be >= 3";
  if (!(refine_max_step_share > 0.0) || !(refine_min_pull_depth_ratio > 0.0)) {
    return "registration.refine_max_step_share and refine_min_pull_depth_ratio must be > 0";
  }
  if (!(refine_far_pull_min_share >= 0.5 && refine_far_pull_min_share <= 1.0)) {
    return "registration.refine_far_pull_min_share must be in [0.5, 1]";
  }
  if (max_pending_points < 0) return "registration.max_pending_points must be >= 0";
  if (max_pending_links < 0) return "registration.max_pending_links must be >= 0";
  return "";
}

std::string ServerMappingOptions::Validate() const {
  if (fusion_neighbours < 0) return "mapping.fusion_neighbours must be >= 0";
  if (!(fusion_radius_px > 0.0)) return "mapping.fusion_radius_px must be > 0";
  if (local_ba_window < 1) return "mapping.local_ba_window must be >= 1";
  if (local_ba_min_new_associations < 0) return "mapping.local_ba_min_new_associations must be >= 0";
  if (local_ba_max_fixed < 0) return "mapping.local_ba_max_fixed must be >= 0";
  if (local_ba_robust_iterations < 0 || local_ba_refine_iterations < 0 ||
      local_ba_robust_iterations + local_ba_refine_iterations == 0) {
    return "mapping.local_ba_*_iterations must be >= 0 and not both 0";
  }
  if (recent_keyframes < 0) return "mapping.recent_keyframes must be >= 0";
  if (!(duplicate_distance_ratio >= 0.0 && duplicate_distance_ratio < 1.0)) {
    return "mapping.duplicate_distance_ratio must be in [0, 1)";
  }
  if (!(duplicate_max_angle_deg >= 0.0)) return "mapping.duplicate_max_angle_deg must be >= 0";
  if (!(overlap_weld_depth_ratio >= 0.0 && overlap_weld_depth_ratio <= 10.0)) {
    return "mapping.overlap_weld_depth_ratio must be in [0, 10]";
  }
  return "";
}

std::string PlaceMatchingOptions::Validate() const {
  if (auto e = candidates.Validate(); !e.empty()) return "place.candidates: " + e;
  if (auto e = verification.Validate(); !e.empty()) return "place.verification: " + e;
  if (vocabulary_levels_up < -1) return "place.vocabulary_levels_up must be >= 0, or -1 (automatic)";
  if (candidate_window < 0) return "place.candidate_window must be >= 0";
  if (!(fusion_min_common_ratio >= 0.0 && fusion_min_common_ratio <= 1.0)) {
    return "place.fusion_min_common_ratio must be in [0, 1]";
  }
  if (loop_min_map_keyframes < 2) return "place.loop_min_map_keyframes must be >= 2";
  if (consistency_window_keyframes < 1) return "place.consistency_window_keyframes must be >= 1";
  if (!(consistency_max_angle_deg > 0.0)) return "place.consistency_max_angle_deg must be > 0";
  if (!(consistency_max_scale_diff > 0.0)) return "place.consistency_max_scale_diff must be > 0";
  if (!(consistency_max_position_ratio > 0.0)) return "place.consistency_max_position_ratio must be > 0";
  if (!(loop_max_correction_angle_deg > 0.0)) return "place.loop_max_correction_angle_deg must be > 0";
  if (!(loop_max_correction_path_ratio > 0.0)) return "place.loop_max_correction_path_ratio must be > 0";
  if (min_keyframes_between_loops < 0) return "place.min_keyframes_between_loops must be >= 0";
  return "";
}

std::string OptimizationJobOptions::Validate() const {
  if (global_ba_iterations < 1) return "optimization.global_ba_iterations must be >= 1";
  if (global_ba_threads < 1) return "optimization.global_ba_threads must be >= 1";
  if (global_ba_max_free_keyframes < 0) return "optimization.global_ba_max_free_keyframes must be >= 0";
  if (!(global_ba_min_parallax_deg >= 0.0 && global_ba_min_parallax_deg < 90.0)) {
    return "optimization.global_ba_min_parallax_deg must be in [0, 90)";
  }
  if (!(global_ba_pause_factor >= 0.0)) return "optimization.global_ba_pause_factor must be >= 0";
  if (pose_graph_iterations < 1) return "optimization.pose_graph_iterations must be >= 1";
  return "";
}

std::string RedundancyOptions::Validate() const {
  if (!(theta > 0.0 && theta <= 1.0)) return "redundancy.theta must be in (0, 1]";
  if (min_map_keyframes < 3) return "redundancy.min_map_keyframes must be >= 3";
  if (!(revisit_distance_ratio >= 0.0 && revisit_distance_ratio < 1.0)) {
    return "redundancy.revisit_distance_ratio must be in [0, 1) (0: off)";
  }
  if (!(revisit_max_angle_deg > 0.0 && revisit_max_angle_deg <= 90.0)) {
    return "redundancy.revisit_max_angle_deg must be in (0, 90]";
  }
  if (!(revisit_min_age_s >= 0.0)) return "redundancy.revisit_min_age_s must be >= 0";
  if (!(revisit_settle_s >= 0.0)) return "redundancy.revisit_settle_s must be >= 0";
  if (!(revisit_min_covered >= 0.0 && revisit_min_covered <= 1.0)) {
    return "redundancy.revisit_min_covered must be in [0, 1]";
  }
  if (!(revisit_sweep_min_covered >= 0.0 && revisit_sweep_min_covered <= 1.0)) {
    return "redundancy.revisit_sweep_min_covered must be in [0, 1]";
  }
  return "";
}

std::string ServerOptions::Validate() const {
  if (auto e = map.Validate(); !e.empty()) return "map: " + e;
  for (const std::string& e : {registration.Validate(), mapping.Validate(), place.Validate(), optimization.Validate(),
                               redundancy.Validate()}) {
    if (!e.empty()) return e;
  }
  if (max_agents < 1 || max_agents > 65535) return "max_agents must be in 1..65535";
  if (!(agent_slot_release_s >= 0.0)) return "agent_slot_release_s must be >= 0 (0: never)";
  if (max_queued_batches_per_agent < 1) return "max_queued_batches_per_agent must be >= 1";
  if (max_queued_bytes_per_agent < (size_t{1} << 20)) return "max_queued_bytes_per_agent must be >= 1 MiB";
  if (max_segments_per_agent < 1) return "max_segments_per_agent must be >= 1";
  if (neighbourhood_k < 0) return "neighbourhood_k must be >= 0";
  if (!(share_own_keyframes_after_s >= 0.0)) return "share_own_keyframes_after_s must be >= 0";
  return "";
}

}  // namespace ccm
