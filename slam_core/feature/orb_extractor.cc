#include "slam_core/feature/orb_extractor.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "slam_core/feature/quadtree_distribution.h"
#include "slam_core/feature/steered_brief.h"

namespace ccm {
namespace {

/// Keypoints per level from the geometric series n0 * (1/s)^l summing to num_features:
/// the number per level is proportional to the level's image side length (ORB-SLAM).
std::vector<int> FeaturesPerLevel(int num_features, int num_levels, double scale_factor) {
  std::vector<int> per_level(num_levels, 0);
  const double f = 1.0 / scale_factor;
  double desired = num_features * (1.0 - f) / (1.0 - std::pow(f, num_levels));
  int total = 0;
  for (int l = 0; l + 1 < num_levels; ++l, desired *= f) {
    per_level[l] = static_cast<int>(std::lround(desired));
    total += per_level[l];
  }
  per_level[num_levels - 1] = std::max(num_features - total, 0);
  return per_level;
}

/// FAST on [x0, x1) x [y0, y1) of `level`; corners come back in level coordinates, only
/// those inside the rectangle (FAST needs 3 px of context, taken from the image around it).
void FastInRect(const cv::Mat& level, int x0, int y0, int x1, int y1, int threshold,
                std::vector<cv::KeyPoint>* out) {
  const cv::Rect roi(x0 - 3, y0 - 3, x1 - x0 + 6, y1 - y0 + 6);
  std::vector<cv::KeyPoint> found;
  cv::FAST(level(roi), found, threshold, /*nonmaxSuppression=*/true);
  for (cv::KeyPoint& kp : found) {
    kp.pt.x += static_cast<float>(roi.x);
    kp.pt.y += static_cast<float>(roi.y);
    if (kp.pt.x >= x0 && kp.pt.x < x1 && kp.pt.y >= y0 && kp.pt.y < y1) out->push_back(kp);
  }
}

}  // namespace

std::string OrbExtractorOptions::Validate() const {
  if (num_features < 1) return "num_features must be >= 1";
  if (num_levels < 1 || num_levels > 32) return "num_levels must be in [1, 32]";
  if (!(scale_factor > 1.0) || scale_factor > 4.0) return "scale_factor must be in (1, 4]";
  if (ini_fast_threshold < 1 || ini_fast_threshold > 254) {
    return "ini_fast_threshold must be in [1, 254]";
  }
  if (min_fast_threshold < 1 || min_fast_threshold > ini_fast_threshold) {
    return "min_fast_threshold must be in [1, ini_fast_threshold]";
  }
  if (edge_border_px < kMinPatchBorder) {
    return "edge_border_px must be >= " + std::to_string(kMinPatchBorder) +
           " (orientation and descriptor patches)";
  }
  if (cell_size_px < 8) return "cell_size_px must be >= 8";
  if (!(adapt_high_ratio >= 0.0)) return "adapt_high_ratio must be >= 0 (0: fixed threshold)";
  if (adapt_high_ratio > 0.0 && !(adapt_low_ratio > 0.0 && adapt_low_ratio < adapt_high_ratio)) {
    return "adapt_low_ratio must be in (0, adapt_high_ratio)";
  }
  if (max_fast_threshold < ini_fast_threshold || max_fast_threshold > 254) {
    return "max_fast_threshold must be in [ini_fast_threshold, 254]";
  }
  return "";
}

OrbExtractor::OrbExtractor(const OrbExtractorOptions& options)
    : options_(options),
      pyramid_(ScalePyramid::Make(options.num_levels, options.scale_factor)),
      features_per_level_(
          FeaturesPerLevel(options.num_features, options.num_levels, options.scale_factor)),
      level_threshold_(options.num_levels, options.ini_fast_threshold) {
  assert(options_.Validate().empty());
}

void OrbExtractor::BuildPyramid(const cv::Mat& gray) {
  levels_.resize(options_.num_levels);
  levels_[0] = gray;
  for (int l = 1; l < options_.num_levels; ++l) {
    const cv::Size size(static_cast<int>(std::lround(gray.cols * pyramid_.inv_scale[l])),
                        static_cast<int>(std::lround(gray.rows * pyramid_.inv_scale[l])));
    if (size.width <= 2 * options_.edge_border_px || size.height <= 2 * options_.edge_border_px) {
      levels_[l] = cv::Mat();  // too small to hold a keypoint: no features on this level
      continue;
    }
    cv::resize(levels_[l - 1], levels_[l], size, 0, 0, cv::INTER_LINEAR);
  }
}

size_t OrbExtractor::DetectFast(const cv::Mat& level, int threshold, std::vector<cv::KeyPoint>* corners) const {
  const int b = options_.edge_border_px;
  const int x1 = level.cols - b, y1 = level.rows - b;
  corners->clear();
  FastInRect(level, b, b, x1, y1, threshold, corners);
  const size_t found = corners->size();
  // Cells without a corner at the level's threshold get a second chance at the initial one
  // (if the level's was raised) and then at the low one, so weakly textured regions still
  // contribute keypoints.
  const int cell = options_.cell_size_px;
  const int cols = (x1 - b + cell - 1) / cell, rows = (y1 - b + cell - 1) / cell;
  std::vector<int> count(cols * rows, 0);
  for (const cv::KeyPoint& kp : *corners) {
    const int cx = std::min(cols - 1, (static_cast<int>(kp.pt.x) - b) / cell);
    const int cy = std::min(rows - 1, (static_cast<int>(kp.pt.y) - b) / cell);
    ++count[cy * cols + cx];
  }
  for (int cy = 0; cy < rows; ++cy) {
    for (int cx = 0; cx < cols; ++cx) {
      if (count[cy * cols + cx] > 0) continue;
      const int xa = b + cx * cell, ya = b + cy * cell;
      const int xb = std::min(xa + cell, x1), yb = std::min(ya + cell, y1);
      const size_t before = corners->size();
      if (threshold > options_.ini_fast_threshold) {
        FastInRect(level, xa, ya, xb, yb, options_.ini_fast_threshold, corners);
      }
      if (corners->size() == before && options_.min_fast_threshold < options_.ini_fast_threshold) {
        FastInRect(level, xa, ya, xb, yb, options_.min_fast_threshold, corners);
      }
    }
  }
  return found;
}

void OrbExtractor::AdaptThreshold(int l, size_t found) {
  if (options_.adapt_high_ratio <= 0.0) return;
  int& t = level_threshold_[l];
  const double target = std::max(features_per_level_[l], 1);
  const int step = std::max(1, t / 8);
  if (found > options_.adapt_high_ratio * target) {
    t = std::min(options_.max_fast_threshold, t + step);
  } else if (found < options_.adapt_low_ratio * target) {
    t = std::max(options_.ini_fast_threshold, t - step);
  }
}

FrameFeatures OrbExtractor::Extract(const cv::Mat& image) {
  FrameFeatures out;
  if (image.empty() || image.depth() != CV_8U) return out;
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.cols <= 2 * options_.edge_border_px || gray.rows <= 2 * options_.edge_border_px) {
    return out;
  }
  BuildPyramid(gray);
  out.keypoints.reserve(options_.num_features);
  out.descriptors.reserve(options_.num_features);
  const int b = options_.edge_border_px;
  std::vector<cv::KeyPoint> corners;
  int carry = 0;  // keypoints a level could not provide are asked from the next one
  for (int l = 0; l < options_.num_levels; ++l) {
    const cv::Mat& level = levels_[l];
    const int target = features_per_level_[l] + carry;
    if (level.empty() || target <= 0) {
      carry = target;
      continue;
    }
    AdaptThreshold(l, DetectFast(level, level_threshold_[l], &corners));
    const std::vector<int> kept = DistributeQuadtree(
        corners, static_cast<float>(b), static_cast<float>(b), static_cast<float>(level.cols - b),
        static_cast<float>(level.rows - b), target);
    carry = target - static_cast<int>(kept.size());
    if (kept.empty()) continue;
    // Descriptors are computed on a smoothed image (BRIEF is noise sensitive); orientation on
    // the raw level.
    cv::GaussianBlur(level, blurred_, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
    // Level pixel centres map to level-0 pixel centres through the exact resize ratio.
    const double sx = static_cast<double>(gray.cols) / level.cols;
    const double sy = static_cast<double>(gray.rows) / level.rows;
    for (int i : kept) {
      const int x = static_cast<int>(corners[i].pt.x), y = static_cast<int>(corners[i].pt.y);
      Keypoint kp;
      kp.angle_deg = IntensityCentroidAngle(level, x, y);
      kp.u = static_cast<float>((x + 0.5) * sx - 0.5);
      kp.v = static_cast<float>((y + 0.5) * sy - 0.5);
      kp.response = corners[i].response;
      kp.level = l;
      out.keypoints.push_back(kp);
      out.descriptors.push_back(SteeredBrief(blurred_, x, y, kp.angle_deg));
    }
  }
  return out;
}

}  // namespace ccm
