// Value types of ORB features shared by extraction, matching, the map, place recognition
// and the message conversion layer. A keypoint is 20 bytes on the wire (CCM-SLAM figure).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ccm {

/// 256-bit rotated BRIEF descriptor.
using OrbDescriptor = std::array<uint8_t, 32>;

/// Hamming distance between two descriptors (0..256).
inline int HammingDistance(const OrbDescriptor& a, const OrbDescriptor& b) {
  int d = 0;
  for (int i = 0; i < 32; i += 8) {
    uint64_t x, y;
    __builtin_memcpy(&x, a.data() + i, 8);
    __builtin_memcpy(&y, b.data() + i, 8);
    d += __builtin_popcountll(x ^ y);
  }
  return d;
}

/// A detected keypoint in level-0 (full resolution, distorted) pixel coordinates.
struct Keypoint {
  float u = 0, v = 0;      ///< pixel position in the original image [px]
  float angle_deg = 0;     ///< orientation (intensity centroid), [0, 360)
  float response = 0;      ///< FAST score at its level
  int level = 0;           ///< pyramid level it was detected on
};

/// Scale factors of the image pyramid; shared by extraction, matching and optimization
/// (measurement sigma of a level-l keypoint is scale(l) px).
struct ScalePyramid {
  int num_levels = 8;
  double scale_factor = 1.2;
  std::vector<double> scale;      ///< scale[l] = scale_factor^l
  std::vector<double> inv_scale;  ///< 1 / scale[l]
  std::vector<double> sigma2;     ///< scale[l]^2
  std::vector<double> inv_sigma2;

  static ScalePyramid Make(int num_levels, double scale_factor) {
    ScalePyramid p;
    p.num_levels = num_levels;
    p.scale_factor = scale_factor;
    double s = 1.0;
    for (int l = 0; l < num_levels; ++l, s *= scale_factor) {
      p.scale.push_back(s);
      p.inv_scale.push_back(1.0 / s);
      p.sigma2.push_back(s * s);
      p.inv_sigma2.push_back(1.0 / (s * s));
    }
    return p;
  }
};

/// Features of one image: keypoints[i] is described by descriptors[i].
struct FrameFeatures {
  std::vector<Keypoint> keypoints;
  std::vector<OrbDescriptor> descriptors;
  size_t size() const { return keypoints.size(); }
};

}  // namespace ccm
