#include "slam_core/feature/keypoint_grid.h"

#include <algorithm>
#include <cmath>

namespace ccm {

KeypointGrid::KeypointGrid(const FrameFeatures& features, int width_px, int height_px,
                           float cell_size_px) {
  const float cell = std::max(cell_size_px, 1.f);
  inv_cell_ = 1.f / cell;
  cols_ = std::max(1, static_cast<int>(std::ceil(std::max(width_px, 1) * inv_cell_)));
  rows_ = std::max(1, static_cast<int>(std::ceil(std::max(height_px, 1) * inv_cell_)));
  points_.reserve(features.size());
  for (const Keypoint& kp : features.keypoints) points_.push_back({kp.u, kp.v, kp.level});
  // Counting sort into cells (CSR layout: one allocation, cache friendly queries).
  cell_start_.assign(cols_ * rows_ + 1, 0);
  for (const Point& p : points_) ++cell_start_[CellY(p.v) * cols_ + CellX(p.u) + 1];
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_items_.resize(points_.size());
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int i = 0; i < static_cast<int>(points_.size()); ++i) {
    const Point& p = points_[i];
    cell_items_[fill[CellY(p.v) * cols_ + CellX(p.u)]++] = i;
  }
}

// Keypoints outside the image (should not happen) are clamped into the border cells so they
// can still be found.
int KeypointGrid::CellX(float u) const {
  return std::clamp(static_cast<int>(std::floor(u * inv_cell_)), 0, cols_ - 1);
}
int KeypointGrid::CellY(float v) const {
  return std::clamp(static_cast<int>(std::floor(v * inv_cell_)), 0, rows_ - 1);
}

std::vector<int> KeypointGrid::FeaturesInArea(float u, float v, float radius, int min_level,
                                              int max_level) const {
  std::vector<int> out;
  FeaturesInArea(u, v, radius, min_level, max_level, &out);
  return out;
}

void KeypointGrid::FeaturesInArea(float u, float v, float radius, int min_level, int max_level,
                                  std::vector<int>* out) const {
  out->clear();
  if (points_.empty() || !(radius >= 0.f) || !std::isfinite(u) || !std::isfinite(v)) return;
  const int cx0 = CellX(u - radius), cx1 = CellX(u + radius);
  const int cy0 = CellY(v - radius), cy1 = CellY(v + radius);
  if (u + radius < 0.f || v + radius < 0.f || u - radius > cols_ / inv_cell_ ||
      v - radius > rows_ / inv_cell_) {
    return;
  }
  for (int cy = cy0; cy <= cy1; ++cy) {
    for (int cx = cx0; cx <= cx1; ++cx) {
      const int c = cy * cols_ + cx;
      for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const Point& p = points_[cell_items_[k]];
        if (p.level < min_level || (max_level >= 0 && p.level > max_level)) continue;
        if (std::fabs(p.u - u) > radius || std::fabs(p.v - v) > radius) continue;
        out->push_back(cell_items_[k]);
      }
    }
  }
  std::sort(out->begin(), out->end());
}

}  // namespace ccm
