// Tracking: estimates the pose of every frame against the agent's local map (motion
// model + projection matching, then the local map), decides when a frame becomes a
// keyframe, relocalizes when lost and opens a new map segment when relocalization keeps
// failing. Synchronous; called by the tracking thread only. Keyframes go to the local
// mapper through the sink given at construction.
#pragma once

#include <functional>
#include <memory>
#include <optional>

#include "slam_core/vo/initializer.h"
#include "slam_core/vo/vo_frame.h"
#include "slam_core/vo/vo_shared.h"

namespace ccm {

enum class TrackingState { kInitializing, kTracking, kLost };
const char* TrackingStateName(TrackingState state);

/// A new keyframe handed from tracking to local mapping.
struct KeyframeJob {
  std::shared_ptr<Map> map;  ///< segment the keyframe belongs to
  std::shared_ptr<KeyFrame> keyframe;
  std::vector<std::shared_ptr<MapPoint>> matches;  ///< per keypoint, tracked points
  bool already_in_map = false;  ///< initialization keyframes are inserted by the tracker
};

struct TrackingResult {
  TrackingState state = TrackingState::kInitializing;
  std::optional<SE3> world_from_cam;  ///< set when the frame was tracked
  int inliers = 0;
  bool new_keyframe = false;
  bool new_segment = false;
  MapId segment;
};

class Tracker {
 public:
  using KeyframeSink = std::function<void(KeyframeJob)>;
  /// `mapper_idle` tells whether local mapping has nothing queued (keyframe decision).
  Tracker(VoShared* shared, KeyframeSink sink, std::function<bool()> mapper_idle);

  TrackingResult Track(VoFrame frame);

  std::shared_ptr<Map> map() const { return map_; }
  KeyframeId reference_kf() const { return reference_kf_ ? reference_kf_->id() : KeyframeId::Invalid(); }
  const std::shared_ptr<KeyFrame>& reference_keyframe() const { return reference_kf_; }
  int segments_started() const { return segments_started_; }
  int resets() const { return resets_; }
  int64_t relocalizations() const { return relocalizations_; }
  /// Frames treated as weak: a lone fallback pose or a sudden inlier drop (VoOptions::weak_lone_fallback_poses,
  /// weak_inlier_drop_ratio).
  int64_t weak_poses() const { return weak_poses_; }
  int64_t road_like_init_attempts() const { return initializer_.road_like_attempts(); }
  /// Keyframes made per KeyframeReason (index = enum value).
  const KeyframeReasonCounts& keyframe_reasons() const { return keyframe_reasons_; }

 private:
  /// The motion from the last frame to a frame stamped `stamp_ns` (needs velocity_).
  SE3 PredictedMotion(int64_t stamp_ns) const;
  bool TrackWithMotionModel(VoFrame* f);
  bool TrackReferenceKeyframe(VoFrame* f);
  bool Relocalize(VoFrame* f);
  /// Matches the frame to `points` by appearance, then PnP RANSAC + pose optimization.
  bool RelocalizeAgainst(VoFrame* f, const std::vector<std::shared_ptr<MapPoint>>& points);
  /// Points of a relocalization candidate and of its best covisible keyframes.
  std::vector<std::shared_ptr<MapPoint>> PointsAround(const KeyFrame& kf) const;
  int TrackLocalMap(VoFrame* f);
  int OptimizeFramePose(VoFrame* f);
  int OptimizeFramePoseRobustly(VoFrame* f);
  int RansacFramePose(VoFrame* f);
  KeyframeReason NeedNewKeyframe(const VoFrame& f, int inliers) const;
  double ImageCoverage(const VoFrame& f) const;
  double MedianDepth(const VoFrame& f) const;
  double BaselineOverDepth(const VoFrame& f) const;
  /// The reference keyframe's measures for the keyframe decision, taken on its frame.
  void RememberKeyframeFrame(const VoFrame& f);
  void CreateKeyframe(const VoFrame& f);
  void StartNewSegment();
  void ResetToInitialization();
  void OnInitialized(const InitializationResult& init);
  std::vector<std::shared_ptr<KeyFrame>> LocalKeyframes(const VoFrame& f) const;

  VoShared* shared_;
  KeyframeSink sink_;
  std::function<bool()> mapper_idle_;
  Initializer initializer_;
  std::shared_ptr<Map> map_;
  TrackingState state_ = TrackingState::kInitializing;
  std::optional<VoFrame> last_frame_;
  int64_t relocalizations_ = 0;
  int64_t weak_poses_ = 0;
  std::optional<SE3> velocity_;  ///< cam_from_world(k) * world_from_cam(k-1)
  int64_t velocity_dt_ns_ = 0;   ///< stamp(k) - stamp(k-1) of that motion
  std::shared_ptr<KeyFrame> reference_kf_;
  int reference_tracked_ = 0;      ///< points the reference keyframe tracked when created
  int reference_inliers_ = 0;      ///< local-map inliers of the frame it was made from (0: none)
  /// The local keyframe sharing the most points with the last frame (LocalKeyframes' first).
  std::shared_ptr<KeyFrame> covisible_reference_;
  double reference_coverage_ = 0;  ///< its image coverage (ImageCoverage) when created
  double reference_median_depth_ = 0;  ///< median depth of its tracked points when created
  double horizontal_fov_rad_ = 0;      ///< for the keyframe rule of fast turns
  int64_t last_kf_frame_index_ = 0;
  int64_t last_kf_stamp_ns_ = 0;
  int64_t last_reloc_frame_index_ = -1000;
  /// The last tracked frame's pose came from the motion model (not the reference-keyframe
  /// fallback or a relocalization).
  bool last_by_motion_model_ = false;
  /// Local-map inliers of the last tracked frame (0: none since the last reset or loss).
  int last_inliers_ = 0;
  /// After a weak pose (see Track): the tracked frame before it, which the next velocity is
  /// measured from.
  struct MotionBase {
    SE3 world_from_cam;
    int64_t stamp_ns = 0;
  };
  std::optional<MotionBase> before_weak_;
  int lost_frames_ = 0;
  int segments_started_ = 0;
  KeyframeReasonCounts keyframe_reasons_{};
  int resets_ = 0;  ///< initializations discarded because tracking failed right after
};

}  // namespace ccm
