// Procedural, mip-mapped grey-level textures for the simulator's planar surfaces.
// Why: a feature detector must see a scene that behaves like a real one (corners at many
// scales, no periodic patterns, some weakly textured areas), and the renderer needs
// anti-aliased lookups, hence a full mip pyramid per texture.
// Use: MakeProceduralTexture(style, size, seed) once at world build; Sample() per pixel.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace ccm::sim {

/// How much structure a texture carries.
enum class TextureStyle {
  kRich = 0,      ///< dense marks at all scales (boxes, posters, cluttered walls)
  kMixed = 1,     ///< rich patches next to weakly textured ones (floors, most walls)
  kWeak = 2,      ///< mostly smooth with few marks (ceilings, painted walls)
  kFlat = 3,      ///< constant grey value (markers, tests)
};

/// Parses "rich" / "mixed" / "weak" / "flat"; false if unknown.
bool ParseTextureStyle(const std::string& name, TextureStyle* style);
const char* TextureStyleName(TextureStyle style);

/// A grey texture with its mip pyramid (level 0 = full resolution, each level half size).
/// Immutable after construction, safe to share between threads.
class MipTexture {
 public:
  /// Takes a CV_8UC1 base image whose texels are texel_m metres wide and builds the pyramid.
  MipTexture(const cv::Mat& base, double texel_m);

  /// Trilinear lookup at surface coordinates (metres from the texture origin); `lod` is
  /// the mip level (log2 of texels per pixel footprint), clamped to the pyramid range.
  /// Coordinates outside the texture clamp to the border. Returns grey value 0..255.
  float Sample(double u_m, double v_m, float lod) const;

  double texel_m() const { return texel_m_; }
  float inv_texel_m() const { return inv_texel_m_; }
  int levels() const { return static_cast<int>(levels_.size()); }
  const cv::Mat& level(int i) const { return levels_[i]; }

 private:
  float Bilinear(int level, float x, float y) const;

  std::vector<cv::Mat> levels_;
  double texel_m_;
  float inv_texel_m_;  // multiplications instead of divisions in the per-pixel lookup
};

// Inline: called once or twice per rendered pixel.
inline float MipTexture::Bilinear(int level, float x, float y) const {
  const cv::Mat& img = levels_[level];
  const float max_x = static_cast<float>(img.cols - 1);
  const float max_y = static_cast<float>(img.rows - 1);
  x = std::min(std::max(x, 0.0f), max_x);
  y = std::min(std::max(y, 0.0f), max_y);
  const int x0 = std::min(static_cast<int>(x), img.cols - 2 < 0 ? 0 : img.cols - 2);
  const int y0 = std::min(static_cast<int>(y), img.rows - 2 < 0 ? 0 : img.rows - 2);
  const int x1 = std::min(x0 + 1, img.cols - 1);
  const int y1 = std::min(y0 + 1, img.rows - 1);
  const float fx = x - static_cast<float>(x0);
  const float fy = y - static_cast<float>(y0);
  const uchar* r0 = img.ptr<uchar>(y0);
  const uchar* r1 = img.ptr<uchar>(y1);
  const float top = r0[x0] + fx * (static_cast<float>(r0[x1]) - r0[x0]);
  const float bottom = r1[x0] + fx * (static_cast<float>(r1[x1]) - r1[x0]);
  return top + fy * (bottom - top);
}

inline float MipTexture::Sample(double u_m, double v_m, float lod) const {
  const float max_level = static_cast<float>(levels_.size() - 1);
  lod = std::min(std::max(lod, 0.0f), max_level);
  const int l0 = static_cast<int>(lod);
  const float frac = lod - static_cast<float>(l0);
  const float x = static_cast<float>(u_m) * inv_texel_m_;
  const float y = static_cast<float>(v_m) * inv_texel_m_;
  // Texel centres: level l texel i covers [i, i+1) * 2^l level-0 texels.
  const float s0 = 1.0f / static_cast<float>(1 << l0);
  const float a = Bilinear(l0, x * s0 - 0.5f, y * s0 - 0.5f);
  if (frac <= 1e-3f || l0 + 1 >= levels()) return a;
  const float s1 = 0.5f * s0;
  const float b = Bilinear(l0 + 1, x * s1 - 0.5f, y * s1 - 0.5f);
  return a + frac * (b - a);
}

/// Parameters of one procedural texture.
struct TextureRecipe {
  TextureStyle style = TextureStyle::kMixed;
  double width_m = 1.0;       ///< extent along the surface's u axis
  double height_m = 1.0;      ///< extent along the v axis
  double texel_m = 0.008;     ///< texel size at level 0 [m]
  std::uint64_t seed = 1;     ///< same recipe + seed => identical texture
  float base_grey = 128.0f;   ///< mean grey level 0..255 (kFlat: the constant value)
};

/// Draws a texture: multi-octave value noise, a low-frequency density field that leaves
/// some areas weakly textured, and random shapes (rectangles, ellipses, polygons, lines,
/// text-like marks) with sizes spread log-uniformly over two decades. Deterministic.
cv::Mat DrawProceduralTexture(const TextureRecipe& recipe);

}  // namespace ccm::sim
