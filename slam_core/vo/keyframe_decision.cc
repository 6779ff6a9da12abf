#include "slam_core/vo/keyframe_decision.h"

namespace ccm {

std::string KeyframeDecisionOptions::Validate() const {
  if (max_frames < 1 || min_frames < 0 || min_frames > max_frames) {
    return "need 0 <= kf_min_frames <= kf_max_frames and kf_max_frames >= 1";
  }
  if (tracked_ratio <= 0 || tracked_ratio > 1) return "kf_tracked_ratio must be in (0, 1]";
  if (urgent_ratio < 0 || urgent_ratio > tracked_ratio) {
    return "kf_urgent_ratio (" + std::to_string(urgent_ratio) + ") must be in [0, kf_tracked_ratio (" +
           std::to_string(tracked_ratio) + ")]: lower kf_urgent_ratio with kf_tracked_ratio";
  }
  if (urgent_inliers < 0) return "kf_urgent_inliers must be >= 0";
  if (coverage_ratio < 0 || coverage_ratio > 1) return "kf_coverage_ratio must be in [0, 1]";
  if (!(min_interval_s >= 0)) return "kf_min_interval_s must be >= 0";
  if (baseline_depth_ratio < 0) return "kf_baseline_depth_ratio must be >= 0";
  if (max_interval_s < 0) return "kf_max_interval_s must be >= 0";
  if (min_inliers < 0) return "kf_min_inliers must be >= 0";
  if (!(inlier_drop_ratio >= 0 && inlier_drop_ratio < 1)) return "kf_inlier_drop_ratio must be in [0, 1)";
  if (!(turn_fov_share >= 0 && turn_fov_share <= 10)) return "kf_turn_fov_share must be in [0, 10]";
  return "";
}

const char* KeyframeReasonName(KeyframeReason reason) {
  switch (reason) {
    case KeyframeReason::kNone: return "none";
    case KeyframeReason::kTrackedRatio: return "tracked-ratio";
    case KeyframeReason::kCoverage: return "coverage";
    case KeyframeReason::kBaseline: return "baseline";
    case KeyframeReason::kInterval: return "interval";
    case KeyframeReason::kUrgent: return "urgent";
    case KeyframeReason::kInlierDrop: return "inlier-drop";
    case KeyframeReason::kTurn: return "turn";
  }
  return "?";
}

KeyframeReason DecideKeyframe(const KeyframeDecisionOptions& o, const KeyframeDecisionInput& in) {
  if (in.inliers <= o.min_inliers || in.frames_since_kf < 1) return KeyframeReason::kNone;
  const double ratio = in.reference_points > 0 ? static_cast<double>(in.inliers) / in.reference_points : 0.0;
  // About to lose the map: new points now, whatever mapping is doing.
  if (ratio < o.urgent_ratio || in.inliers < o.urgent_inliers) return KeyframeReason::kUrgent;
  if (o.turn_fov_share > 0 && in.turn_fov_share >= o.turn_fov_share && ratio < o.tracked_ratio) {
    return KeyframeReason::kTurn;
  }
  if (in.frames_since_kf < o.min_frames) return KeyframeReason::kNone;
  // 1 ms slack: stamps of a 20 Hz camera 4 frames apart are 0.2 s give or take rounding.
  if (in.seconds_since_kf + 1e-3 < o.min_interval_s) return KeyframeReason::kNone;
  if (!in.mapper_idle && in.frames_since_kf < o.max_frames) return KeyframeReason::kNone;
  if (ratio < o.tracked_ratio) return KeyframeReason::kTrackedRatio;
  if (in.reference_inliers > 0 && in.inliers < o.inlier_drop_ratio * in.reference_inliers) {
    return KeyframeReason::kInlierDrop;
  }
  if (o.coverage_ratio > 0 && in.reference_coverage > 0 && in.coverage < o.coverage_ratio * in.reference_coverage) {
    return KeyframeReason::kCoverage;
  }
  if (o.baseline_depth_ratio > 0 && in.baseline_over_depth > o.baseline_depth_ratio) return KeyframeReason::kBaseline;
  // Something changed (a few points lost) and it has been long: keep the map fresh.
  if (o.max_interval_s > 0 && in.seconds_since_kf > o.max_interval_s && ratio < 0.98) return KeyframeReason::kInterval;
  return KeyframeReason::kNone;
}

}  // namespace ccm
