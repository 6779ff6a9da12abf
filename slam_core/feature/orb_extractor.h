// ORB feature extraction in the ORB-SLAM style: an image pyramid, FAST per grid cell with a
// threshold fallback, a quadtree per level that keeps the strongest corner of each node so
// keypoints spread over the whole image, intensity-centroid orientation and steered BRIEF.
// Owned by one tracking thread: Extract() reuses internal buffers, so use one extractor per
// thread. Output is deterministic for a given image sequence and options (the adaptive FAST
// threshold carries over from one frame to the next).
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "slam_core/feature/orb_types.h"

namespace ccm {

struct OrbExtractorOptions {
  int num_features = 1000;      ///< keypoints over all levels (upper bound)
  int num_levels = 8;           ///< pyramid levels
  double scale_factor = 1.2;    ///< scale between consecutive levels (> 1)
  int ini_fast_threshold = 20;  ///< FAST intensity threshold [grey levels]
  int min_fast_threshold = 7;   ///< fallback threshold for cells where the first finds none
  int edge_border_px = 19;      ///< keypoints keep this distance to each level's border [px]
  int cell_size_px = 30;        ///< FAST grid cell size on every level [px]
  /// Adaptive FAST threshold per pyramid level. On dense texture the fixed threshold finds
  /// ~20 corners per keypoint kept, and scoring and suppressing them was most of the
  /// extraction time. After each frame, a level that found more than adapt_high_ratio x
  /// its keypoint target raises its threshold for the next frame, one with fewer than
  /// adapt_low_ratio x lowers it again, never below ini_fast_threshold (weak texture is
  /// handled exactly as with a fixed threshold) nor above max_fast_threshold. Cells left
  /// empty by a raised threshold are retried at ini_fast_threshold, then at
  /// min_fast_threshold. adapt_high_ratio = 0: fixed threshold.
  double adapt_high_ratio = 4.0;
  double adapt_low_ratio = 2.0;
  int max_fast_threshold = 60;

  /// Empty if usable, else what is wrong ("num_levels must be in [1, 32]").
  std::string Validate() const;
};

class OrbExtractor {
 public:
  /// Options must be valid (Validate() empty); invalid options are a programming error.
  explicit OrbExtractor(const OrbExtractorOptions& options);

  /// Extracts features from an 8-bit image (grey, or BGR/BGRA converted to grey).
  /// Keypoints are in level-0 pixel coordinates of the (distorted) input image, ordered by
  /// level. An empty or too small image yields no features.
  FrameFeatures Extract(const cv::Mat& image);

  const OrbExtractorOptions& options() const { return options_; }
  const ScalePyramid& pyramid() const { return pyramid_; }
  /// Target number of keypoints per level (geometric series, level 0 gets the most).
  const std::vector<int>& features_per_level() const { return features_per_level_; }
  /// FAST threshold each level will use on the next frame (adaptive; options().ini otherwise).
  const std::vector<int>& level_thresholds() const { return level_threshold_; }
  /// Pyramid images of the last Extract() call (level 0 is the grey input).
  const std::vector<cv::Mat>& level_images() const { return levels_; }

 private:
  void BuildPyramid(const cv::Mat& gray);
  /// FAST corners of one level (level coordinates), ini threshold with per-cell fallback.
  /// Returns how many corners the level's own threshold found (before cell retries).
  size_t DetectFast(const cv::Mat& level, int threshold, std::vector<cv::KeyPoint>* corners) const;
  /// Moves level l's threshold towards adapt_low..high_ratio x its target.
  void AdaptThreshold(int l, size_t found);

  OrbExtractorOptions options_;
  ScalePyramid pyramid_;
  std::vector<int> features_per_level_;
  std::vector<cv::Mat> levels_;
  cv::Mat blurred_;
  std::vector<int> level_threshold_;  // adaptive FAST threshold per level
};

}  // namespace ccm
