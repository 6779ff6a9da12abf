// Spatial index of a frame's keypoints for radius queries (matching by projection, window
// search at initialization). Built over the keypoints' DISTORTED pixel positions, the
// coordinates FrameFeatures stores and CameraModel::Project predicts, so it works for any
// camera model without undistorting the grid bounds. Immutable after construction; safe to
// query from several threads.
#pragma once

#include <cstddef>
#include <vector>

#include "slam_core/feature/orb_types.h"

namespace ccm {

class KeypointGrid {
 public:
  KeypointGrid() = default;
  /// Grid over [0, width_px) x [0, height_px) with square cells of cell_size_px.
  KeypointGrid(const FrameFeatures& features, int width_px, int height_px,
               float cell_size_px = 10.f);

  /// Indices of keypoints with |u_k - u| <= radius and |v_k - v| <= radius (a square window,
  /// as ORB-SLAM) and min_level <= level <= max_level (max_level < 0: no upper bound).
  /// Sorted ascending.
  std::vector<int> FeaturesInArea(float u, float v, float radius, int min_level = 0,
                                  int max_level = -1) const;
  /// Same, appending to *out after clearing it (no allocation once out has capacity).
  void FeaturesInArea(float u, float v, float radius, int min_level, int max_level,
                      std::vector<int>* out) const;

  size_t size() const { return points_.size(); }

 private:
  struct Point {
    float u, v;
    int level;
  };
  int CellX(float u) const;
  int CellY(float v) const;

  float inv_cell_ = 0.1f;
  int cols_ = 0, rows_ = 0;
  std::vector<Point> points_;
  std::vector<int> cell_start_;  ///< CSR: cell c holds cell_items_[cell_start_[c] .. [c+1])
  std::vector<int> cell_items_;
};

}  // namespace ccm
