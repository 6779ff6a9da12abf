// Monocular map initialization from two frames: window matching against a reference
// frame, essential/homography model selection and triangulation (ccm_solvers), then a
// two-keyframe bundle adjustment and scale normalization (median depth 1).
// Synchronous; used by the Tracker on the tracking thread.
#pragma once

#include <memory>
#include <optional>

#include "slam_core/vo/vo_frame.h"
#include "slam_core/vo/vo_shared.h"

namespace ccm {

struct InitializationResult {
  std::shared_ptr<Map> map;
  std::shared_ptr<KeyFrame> kf1, kf2;  ///< kf1 at the origin of the segment's frame
  std::vector<std::shared_ptr<MapPoint>> cur_matches;  ///< per keypoint of the current frame
  int num_points = 0;
};

class Initializer {
 public:
  explicit Initializer(VoShared* shared) : shared_(shared) {}
  /// Feeds one frame; returns the new map once two views initialize it.
  std::optional<InitializationResult> AddFrame(const VoFrame& frame);
  void Reset() {
    reference_.reset();
    search_centres_.clear();
    ambiguous_attempts_ = 0;
  }
  /// Two-view attempts that failed on a view that looks planar (homography score ratio
  /// between ORB-SLAM's 0.40 and init_min_homography_ratio) or whose inliers are a third or
  /// more distant points: the runtime tells the user that the road profile would
  /// initialize sooner.
  int64_t road_like_attempts() const { return road_like_attempts_; }

 private:
  std::optional<InitializationResult> TryInitialize(const VoFrame& cur);

  VoShared* shared_;
  std::optional<VoFrame> reference_;
  std::vector<Eigen::Vector2f> search_centres_;  ///< per reference keypoint
  int64_t road_like_attempts_ = 0;
  /// Starts refused because a rival motion explained the view as well, since the last
  /// Reset: from init_max_ambiguous_attempts on the check is skipped (a pure plane always
  /// has a rival, and a late start beats none).
  int ambiguous_attempts_ = 0;
};

}  // namespace ccm
