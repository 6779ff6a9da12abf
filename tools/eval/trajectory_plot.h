// Top-view plot of ground truth vs aligned estimate per agent, drawn with OpenCV for the
// ccm_eval tool: equal axis scale, metre grid with labels, legend, joint ATE in the title.
#pragma once

#include <string>

#include <opencv2/core/mat.hpp>

#include "slam_core/eval/evaluator.h"

namespace ccm::tools {

struct PlotOptions {
  /// "xy", "xz", "yz" or "auto" (drops the axis along which the ground truth extends least:
  /// xy for EuRoC-like z-up worlds, xz for KITTI-like camera worlds).
  std::string plane = "auto";
  int size_px = 1000;  ///< width and height of the image
  bool Validate(std::string* error) const;
};

/// Estimates are drawn under the joint alignment (the collaborative map frame).
cv::Mat RenderTopView(const EvalReport& report, const EvalOptions& eval_options,
                      const PlotOptions& options);

}  // namespace ccm::tools
