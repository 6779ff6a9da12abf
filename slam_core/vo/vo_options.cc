#include "slam_core/vo/vo_options.h"

#include <utility>

namespace ccm {

std::string VoOptions::Validate() const {
  if (auto e = orb.Validate(); !e.empty()) return "orb: " + e;
  if (auto e = map.Validate(); !e.empty()) return "map: " + e;
  if (auto e = bound.Validate(); !e.empty()) return "local map: " + e;
  if (first_id_counter == 0 || first_id_counter >= (uint64_t{1} << 47)) return "first_id_counter must be in [1, 2^47)";
  if (first_segment_counter == 0 || first_segment_counter >= (uint64_t{1} << 31)) {
    return "first_segment_counter must be in [1, 2^31)";
  }
  if (init_num_features < orb.num_features) return "init_num_features must be >= orb.num_features";
  if (init_min_matches < 8) return "init_min_matches must be >= 8";
  if (init_min_homography_ratio <= 0 || init_min_homography_ratio > 1) return "init_min_homography_ratio must be in (0, 1]";
  if (init_fallback_homography_ratio <= 0 || init_fallback_homography_ratio > 1) {
    return "init_fallback_homography_ratio must be in (0, 1]";
  }
  if (init_window_px <= 0) return "init_window_px must be > 0";
  if (init_max_frames < 1) return "init_max_frames must be >= 1";
  if (projection_radius_px <= 0 || local_map_radius_px <= 0) return "search radii must be > 0";
  if (!(max_motion_extrapolation >= 1.0)) return "max_motion_extrapolation must be >= 1";
  if (min_inliers_frame < 3) return "min_inliers_frame must be >= 3";
  if (min_inliers_local_map < min_inliers_frame) return "min_inliers_local_map must be >= min_inliers_frame";
  if (!(weak_inlier_drop_ratio >= 0.0 && weak_inlier_drop_ratio < 1.0)) return "weak_inlier_drop_ratio must be in [0, 1)";
  if (auto e = keyframe.Validate(); !e.empty()) return e;
  if (local_ba_window < 2) return "local_ba_window must be >= 2";
  if (local_ba_max_fixed < 1) return "local_ba_max_fixed must be >= 1";
  if (!(min_baseline_depth_ratio >= 0.0 && min_baseline_depth_ratio < 1.0)) return "min_baseline_depth_ratio must be in [0, 1)";
  if (!(min_triangulation_parallax_deg > 0.0 && min_triangulation_parallax_deg < 90.0)) {
    return "min_triangulation_parallax_deg must be in (0, 90)";
  }
  if (!(init_min_rotation_residual_deg >= 0.0 && init_min_rotation_residual_deg < 90.0)) {
    return "init_min_rotation_residual_deg must be in [0, 90)";
  }
  if (!(init_min_motion_cost_gap >= 0.0 && init_min_motion_cost_gap <= 1e6)) {
    return "init_min_motion_cost_gap must be in [0, 1e6]";
  }
  if (init_max_ambiguous_attempts < 0) return "init_max_ambiguous_attempts must be >= 0";
  if (!(triangulation_parallax_sigmas >= 0.0 && triangulation_parallax_sigmas <= 1000.0)) {
    return "triangulation_parallax_sigmas must be in [0, 1000]";
  }
  if (redundant_kf_ratio <= 0 || redundant_kf_ratio > 1) return "redundant_kf_ratio must be in (0, 1]";
  if (reloc_min_matches < 6) return "reloc_min_matches must be >= 6";
  if (reloc_max_candidates < 1) return "reloc_max_candidates must be >= 1";
  if (reloc_covisible_keyframes < 0) return "reloc_covisible_keyframes must be >= 0";
  if (lost_frames_before_new_segment < 1) return "lost_frames_before_new_segment must be >= 1";
  return "";
}

bool ParseKeyframeReference(const std::string& text, KeyframeReference* out) {
  static const std::pair<const char*, KeyframeReference> kNames[] = {
      {"last", KeyframeReference::kLast},
      {"most_covisible", KeyframeReference::kMostCovisible},
      {"either", KeyframeReference::kEither}};
  for (const auto& [name, value] : kNames) {
    if (text == name) {
      *out = value;
      return true;
    }
  }
  return false;
}

}  // namespace ccm
