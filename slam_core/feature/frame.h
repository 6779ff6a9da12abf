// A camera image as it arrives at the VO: what frame sources (slam_core/io) deliver and the
// VO consumes, so the VO needs no dependency on the readers.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <opencv2/core/mat.hpp>

#include "slam_core/geometry/se3.h"

namespace ccm {

/// One monocular image with its timestamp; ground truth where the source knows it.
struct Frame {
  int64_t stamp_ns = 0;
  cv::Mat image;  ///< 8-bit single channel (CV_8UC1)
  std::optional<SE3> world_from_cam_gt;  ///< exact pose if known (simulator, datasets with GT)
  std::string source_name;               ///< file path or "sim:<agent>:<index>", for messages
};

}  // namespace ccm
