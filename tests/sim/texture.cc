#include "tests/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "tests/sim/sim_random.h"

namespace ccm::sim {

bool ParseTextureStyle(const std::string& name, TextureStyle* style) {
  if (name == "rich") *style = TextureStyle::kRich;
  else if (name == "mixed") *style = TextureStyle::kMixed;
  else if (name == "weak") *style = TextureStyle::kWeak;
  else if (name == "flat") *style = TextureStyle::kFlat;
  else return false;
  return true;
}

const char* TextureStyleName(TextureStyle style) {
  switch (style) {
    case TextureStyle::kRich: return "rich";
    case TextureStyle::kMixed: return "mixed";
    case TextureStyle::kWeak: return "weak";
    case TextureStyle::kFlat: return "flat";
  }
  return "?";
}

MipTexture::MipTexture(const cv::Mat& base, double texel_m)
    : texel_m_(texel_m), inv_texel_m_(static_cast<float>(1.0 / texel_m)) {
  if (base.type() != CV_8UC1 || base.empty()) throw std::invalid_argument("texture must be CV_8UC1");
  levels_.push_back(base.clone());
  while (std::min(levels_.back().cols, levels_.back().rows) > 2) {
    const cv::Mat& prev = levels_.back();
    cv::Mat next;
    cv::resize(prev, next, cv::Size((prev.cols + 1) / 2, (prev.rows + 1) / 2), 0, 0, cv::INTER_AREA);
    levels_.push_back(next);
  }
}

namespace {

// Value noise: a coarse random grid upsampled smoothly to the full texture size.
cv::Mat NoiseOctave(cv::Size size, double cell_texels, Rng& rng) {
  const int gw = std::max(2, static_cast<int>(std::ceil(size.width / cell_texels)) + 2);
  const int gh = std::max(2, static_cast<int>(std::ceil(size.height / cell_texels)) + 2);
  cv::Mat grid(gh, gw, CV_32F);
  for (int r = 0; r < gh; ++r)
    for (int c = 0; c < gw; ++c) grid.at<float>(r, c) = static_cast<float>(rng.Uniform(-1.0, 1.0));
  cv::Mat full;
  cv::resize(grid, full, cv::Size(static_cast<int>(gw * cell_texels), static_cast<int>(gh * cell_texels)), 0, 0,
             cv::INTER_CUBIC);
  return full(cv::Rect(0, 0, size.width, size.height)).clone();
}

// Sum of octaves from `coarse_texels` down to `fine_texels`, amplitude ~ cell^exponent.
cv::Mat FractalNoise(cv::Size size, double coarse_texels, double fine_texels, double exponent, Rng& rng) {
  cv::Mat sum = cv::Mat::zeros(size, CV_32F);
  double norm = 0.0;
  for (double cell = coarse_texels; cell >= fine_texels; cell *= 0.5) {
    const double amp = std::pow(cell / coarse_texels, exponent);
    sum += NoiseOctave(size, cell, rng) * amp;
    norm += amp;
  }
  return sum / std::max(norm, 1e-9);
}

struct ShapeParams {
  double per_m2;       // expected shape count per square metre before density rejection
  double min_size_m;   // log-uniform size range
  double max_size_m;
  double noise_amp;    // grey amplitude of the low-frequency shading noise
  double grain_amp;    // grey amplitude of the fine grain
};

ShapeParams ParamsFor(TextureStyle style) {
  switch (style) {
    case TextureStyle::kRich: return {90.0, 0.012, 0.6, 45.0, 10.0};
    case TextureStyle::kMixed: return {55.0, 0.012, 0.8, 40.0, 8.0};
    case TextureStyle::kWeak: return {3.0, 0.02, 0.4, 14.0, 3.0};
    case TextureStyle::kFlat: return {0.0, 1.0, 1.0, 0.0, 0.0};
  }
  return {};
}

std::string RandomText(Rng& rng) {
  static const char kChars[] = "ABCDEFGHJKLMNPRSTUVWXYZ0123456789-/#";
  std::string s;
  const int n = rng.Int(1, 6);
  for (int i = 0; i < n; ++i) s.push_back(kChars[rng.Int(0, static_cast<int>(sizeof(kChars)) - 2)]);
  return s;
}

// One random mark of about `size_px` texels at `center`, grey `value`.
void DrawShape(cv::Mat& img, cv::Point2d center, double size_px, int value, Rng& rng) {
  const cv::Scalar color(value);
  const double angle = rng.Uniform(0.0, 3.14159265);
  const double aspect = rng.LogUniform(0.25, 1.0);
  const double kind = rng.Uniform();
  auto rotated = [&](double hx, double hy, double px, double py) {
    return cv::Point(static_cast<int>(std::lround(center.x + hx * std::cos(angle) * px - hy * std::sin(angle) * py)),
                     static_cast<int>(std::lround(center.y + hx * std::sin(angle) * px + hy * std::cos(angle) * py)));
  };
  const double hw = 0.5 * size_px;
  const double hh = 0.5 * size_px * aspect;
  if (kind < 0.30) {  // filled (rotated) rectangle
    const cv::Point pts[4] = {rotated(-1, -1, hw, hh), rotated(1, -1, hw, hh), rotated(1, 1, hw, hh),
                              rotated(-1, 1, hw, hh)};
    cv::fillConvexPoly(img, pts, 4, color, cv::LINE_AA);
  } else if (kind < 0.48) {  // filled ellipse
    cv::ellipse(img, cv::Point(static_cast<int>(center.x), static_cast<int>(center.y)),
                cv::Size(std::max(1, static_cast<int>(hw)), std::max(1, static_cast<int>(hh))),
                angle * 57.2958, 0, 360, color, cv::FILLED, cv::LINE_AA);
  } else if (kind < 0.63) {  // irregular polygon (3-6 corners)
    std::vector<cv::Point> pts;
    const int n = rng.Int(3, 6);
    for (int i = 0; i < n; ++i) {
      const double a = angle + 6.2831853 * (i + rng.Uniform(-0.3, 0.3)) / n;
      const double r = hw * rng.Uniform(0.4, 1.0);
      pts.emplace_back(static_cast<int>(center.x + r * std::cos(a)), static_cast<int>(center.y + r * std::sin(a)));
    }
    cv::fillPoly(img, std::vector<std::vector<cv::Point>>{pts}, color, cv::LINE_AA);
  } else if (kind < 0.76) {  // line segment or short polyline
    const int thickness = std::max(1, static_cast<int>(size_px * rng.Uniform(0.01, 0.06)));
    cv::line(img, rotated(-1, 0, hw, hh), rotated(1, 0, hw, hh), color, thickness, cv::LINE_AA);
    if (rng.Uniform() < 0.4) cv::line(img, rotated(1, 0, hw, hh), rotated(1, 1, hw, hw), color, thickness, cv::LINE_AA);
  } else if (kind < 0.90) {  // text-like marks
    const int font = rng.Uniform() < 0.5 ? cv::FONT_HERSHEY_SIMPLEX : cv::FONT_HERSHEY_DUPLEX;
    const double scale = std::max(0.2, size_px / 40.0);
    const int thickness = std::max(1, static_cast<int>(scale * rng.Uniform(0.8, 2.5)));
    cv::putText(img, RandomText(rng), cv::Point(static_cast<int>(center.x - hw), static_cast<int>(center.y)),
                font, scale, color, thickness, cv::LINE_AA);
  } else {  // rectangle outline
    const cv::Point pts[4] = {rotated(-1, -1, hw, hh), rotated(1, -1, hw, hh), rotated(1, 1, hw, hh),
                              rotated(-1, 1, hw, hh)};
    const int thickness = std::max(1, static_cast<int>(size_px * rng.Uniform(0.02, 0.08)));
    cv::polylines(img, std::vector<std::vector<cv::Point>>{{pts, pts + 4}}, true, color, thickness, cv::LINE_AA);
  }
}

}  // namespace

cv::Mat DrawProceduralTexture(const TextureRecipe& r) {
  const int w = std::max(4, static_cast<int>(std::ceil(r.width_m / r.texel_m)));
  const int h = std::max(4, static_cast<int>(std::ceil(r.height_m / r.texel_m)));
  const cv::Size size(w, h);
  if (r.style == TextureStyle::kFlat) return cv::Mat(size, CV_8UC1, cv::Scalar(std::lround(r.base_grey)));
  Rng rng(r.seed);
  const ShapeParams p = ParamsFor(r.style);
  const double texels_per_m = 1.0 / r.texel_m;

  // Low-frequency shading (stains, dirt, uneven paint) from 2 m down to ~3 cm.
  cv::Mat shade = FractalNoise(size, 2.0 * texels_per_m, 0.03 * texels_per_m, 0.6, rng);
  cv::Mat base_f = shade * (2.0 * p.noise_amp) + r.base_grey;
  cv::Mat img;
  base_f.convertTo(img, CV_8UC1);

  // Density field in [0,1]: mixed textures get blank stretches, rich ones stay dense.
  cv::Mat density = FractalNoise(cv::Size(std::max(2, w / 16), std::max(2, h / 16)), 1.5 * texels_per_m / 16.0,
                                 0.4 * texels_per_m / 16.0, 0.5, rng);
  const double area_m2 = r.width_m * r.height_m;
  const long n_shapes = std::lround(area_m2 * p.per_m2);
  for (long i = 0; i < n_shapes; ++i) {
    const double x = rng.Uniform(0.0, w);
    const double y = rng.Uniform(0.0, h);
    const float d = density.at<float>(std::min(static_cast<int>(y / 16), density.rows - 1),
                                      std::min(static_cast<int>(x / 16), density.cols - 1));
    double keep = 1.0;
    if (r.style == TextureStyle::kMixed) keep = std::clamp((d + 0.25) * 2.2, 0.0, 1.0);
    if (r.style == TextureStyle::kRich) keep = std::clamp((d + 0.6) * 1.6, 0.15, 1.0);
    const double u_keep = rng.Uniform();
    const double size_px = rng.LogUniform(p.min_size_m, p.max_size_m) * texels_per_m;
    const int value = rng.Int(15, 240);
    if (u_keep > keep) continue;
    DrawShape(img, cv::Point2d(x, y), size_px, value, rng);
  }

  // Fine grain so that magnified close-ups are not perfectly smooth.
  cv::Mat grain = NoiseOctave(size, 2.0, rng) * p.grain_amp;
  cv::Mat out_f;
  img.convertTo(out_f, CV_32F);
  out_f += grain;
  cv::Mat out;
  out_f.convertTo(out, CV_8UC1);
  return out;
}

}  // namespace ccm::sim
