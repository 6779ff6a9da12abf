#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/sim/texture.h"

namespace ccm::sim {
namespace {

TextureRecipe Recipe(TextureStyle style, std::uint64_t seed) {
  TextureRecipe r;
  r.style = style;
  r.width_m = 2.0;
  r.height_m = 1.5;
  r.seed = seed;
  return r;
}

double MeanGradient(const cv::Mat& img) {
  cv::Mat gx, gy, mag;
  cv::Sobel(img, gx, CV_32F, 1, 0);
  cv::Sobel(img, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, mag);
  return cv::mean(mag)[0];
}

TEST(Texture, SameSeedSameTextureOtherSeedDifferent) {
  const cv::Mat a = DrawProceduralTexture(Recipe(TextureStyle::kMixed, 7));
  const cv::Mat b = DrawProceduralTexture(Recipe(TextureStyle::kMixed, 7));
  const cv::Mat c = DrawProceduralTexture(Recipe(TextureStyle::kMixed, 8));
  ASSERT_EQ(a.size(), cv::Size(250, 188));
  EXPECT_EQ(cv::norm(a, b, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1) / a.total(), 5.0);
}

TEST(Texture, StylesOrderedByStructure) {
  const double rich = MeanGradient(DrawProceduralTexture(Recipe(TextureStyle::kRich, 3)));
  const double weak = MeanGradient(DrawProceduralTexture(Recipe(TextureStyle::kWeak, 3)));
  const double flat = MeanGradient(DrawProceduralTexture(Recipe(TextureStyle::kFlat, 3)));
  EXPECT_GT(rich, 3.0 * weak);
  EXPECT_EQ(flat, 0.0);
}

TEST(Texture, MipmapLevelsHalveAndSampleMatchesTexels) {
  const cv::Mat base = DrawProceduralTexture(Recipe(TextureStyle::kRich, 5));
  const MipTexture tex(base, 0.008);
  ASSERT_GT(tex.levels(), 5);
  for (int l = 1; l < tex.levels(); ++l) {
    EXPECT_EQ(tex.level(l).cols, (tex.level(l - 1).cols + 1) / 2);
    // Area averaging keeps the mean grey level.
    EXPECT_NEAR(cv::mean(tex.level(l))[0], cv::mean(base)[0], 2.0);
  }
  // Texel centres at level 0 return the texel value exactly.
  for (int y : {3, 50, 120})
    for (int x : {0, 77, 249})
      EXPECT_NEAR(tex.Sample((x + 0.5) * 0.008, (y + 0.5) * 0.008, 0.0f), base.at<uchar>(y, x), 1e-3);
  // Between levels the lookup blends linearly.
  const float a = tex.Sample(0.5, 0.5, 2.0f), b = tex.Sample(0.5, 0.5, 3.0f);
  EXPECT_NEAR(tex.Sample(0.5, 0.5, 2.25f), a + 0.25f * (b - a), 1e-3);
}

}  // namespace
}  // namespace ccm::sim
