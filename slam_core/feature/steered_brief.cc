#include "slam_core/feature/steered_brief.h"

#include <array>
#include <cmath>
#include <cstdint>

namespace ccm {
namespace {

struct PointPair {
  int8_t x1, y1, x2, y2;
};
using Pattern = std::array<PointPair, 256>;

/// splitmix64: tiny, fully specified generator, identical on every platform (unlike the
/// distributions of <random>).
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  double Uniform() {  // (0, 1)
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return ((z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
  }
  double Gaussian() {  // Box-Muller, one value per call is enough here
    return std::sqrt(-2.0 * std::log(Uniform())) * std::cos(2.0 * M_PI * Uniform());
  }

 private:
  uint64_t state_;
};

/// One point of the pattern: Gaussian around the centre, inside the pattern disc.
void SamplePoint(SplitMix64* rng, int* x, int* y) {
  constexpr double kSigma = 31.0 / 5.0;  // BRIEF G II: sigma^2 = S^2 / 25 for a 31 px patch
  while (true) {
    *x = static_cast<int>(std::lround(kSigma * rng->Gaussian()));
    *y = static_cast<int>(std::lround(kSigma * rng->Gaussian()));
    if (*x * *x + *y * *y <= kPatternRadius * kPatternRadius) return;
  }
}

Pattern MakePattern() {
  Pattern pattern{};
  SplitMix64 rng(0x5EED0B1Full);  // fixed: the pattern is part of the descriptor format
  for (PointPair& pair : pattern) {
    int x1, y1, x2, y2;
    do {  // tests between near-identical pixels carry no information
      SamplePoint(&rng, &x1, &y1);
      SamplePoint(&rng, &x2, &y2);
    } while ((x1 - x2) * (x1 - x2) + (y1 - y2) * (y1 - y2) < 4);
    pair = {static_cast<int8_t>(x1), static_cast<int8_t>(y1), static_cast<int8_t>(x2),
            static_cast<int8_t>(y2)};
  }
  return pattern;
}

const Pattern& GetPattern() {
  static const Pattern pattern = MakePattern();
  return pattern;
}

/// Half-width of the circular orientation patch for each row offset 0..radius.
const std::array<int, kOrientationRadius + 1>& CircleHalfWidths() {
  static const std::array<int, kOrientationRadius + 1> widths = [] {
    std::array<int, kOrientationRadius + 1> w{};
    for (int dv = 0; dv <= kOrientationRadius; ++dv) {
      w[dv] = static_cast<int>(
          std::floor(std::sqrt(kOrientationRadius * kOrientationRadius - dv * dv + 0.5)));
    }
    return w;
  }();
  return widths;
}

}  // namespace

float IntensityCentroidAngle(const cv::Mat& gray, int x, int y) {
  const auto& half = CircleHalfWidths();
  const uint8_t* center = gray.ptr<uint8_t>(y) + x;
  const int step = static_cast<int>(gray.step1());
  int64_t m10 = 0, m01 = 0;
  for (int u = -half[0]; u <= half[0]; ++u) m10 += u * center[u];
  for (int dv = 1; dv <= kOrientationRadius; ++dv) {
    const uint8_t* below = center + dv * step;
    const uint8_t* above = center - dv * step;
    int64_t row_sum_diff = 0;
    for (int u = -half[dv]; u <= half[dv]; ++u) {
      const int b = below[u], a = above[u];
      row_sum_diff += b - a;
      m10 += u * (b + a);
    }
    m01 += dv * row_sum_diff;
  }
  float angle = static_cast<float>(std::atan2(static_cast<double>(m01), static_cast<double>(m10)) *
                                   180.0 / M_PI);
  if (angle < 0.f) angle += 360.f;
  if (angle >= 360.f) angle -= 360.f;
  return angle;
}

OrbDescriptor SteeredBrief(const cv::Mat& smoothed, int x, int y, float angle_deg) {
  const double a = angle_deg * M_PI / 180.0;
  const float c = static_cast<float>(std::cos(a)), s = static_cast<float>(std::sin(a));
  const uint8_t* center = smoothed.ptr<uint8_t>(y) + x;
  const int step = static_cast<int>(smoothed.step1());
  // Rotates a pattern point into the image and reads the pixel there.
  auto sample = [&](int px, int py) {
    const int rx = cvRound(px * c - py * s);
    const int ry = cvRound(px * s + py * c);
    return center[ry * step + rx];
  };
  OrbDescriptor desc{};
  const Pattern& pattern = GetPattern();
  for (int byte = 0; byte < 32; ++byte) {
    uint8_t bits = 0;
    for (int bit = 0; bit < 8; ++bit) {
      const PointPair& p = pattern[byte * 8 + bit];
      bits |= static_cast<uint8_t>((sample(p.x1, p.y1) < sample(p.x2, p.y2)) << bit);
    }
    desc[byte] = bits;
  }
  return desc;
}

}  // namespace ccm
