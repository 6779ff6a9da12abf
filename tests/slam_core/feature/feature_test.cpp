// Tests of ccm_feature on procedural images: count, spread and levels of keypoints,
// determinism, repeatability and descriptor matching under known rotations and zooms, and the
// keypoint grid against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/feature/orb_extractor.h"
#include "slam_core/feature/steered_brief.h"
#include "synthetic_image.h"

namespace ccm {
namespace {

constexpr int kW = 752, kH = 480;

/// Two views of one big texture: view1 is a window, view2 = view2_from_view1 * view1.
struct ViewPair {
  cv::Mat image1, image2;
  cv::Matx33d view2_from_view1;
};

ViewPair MakeViewPair(double angle_deg, double scale, uint64_t seed) {
  const cv::Mat texture = test::MakeTexture(2 * kW, 2 * kH, seed);
  const cv::Matx33d view1_from_tex = test::Translation(-kW / 2.0, -kH / 2.0);
  const cv::Matx33d v2_from_v1 =
      test::RotateScaleAbout({(kW - 1) / 2.0, (kH - 1) / 2.0}, angle_deg, scale);
  return {test::RenderView(texture, view1_from_tex, {kW, kH}),
          test::RenderView(texture, v2_from_v1 * view1_from_tex, {kW, kH}), v2_from_v1};
}

bool Inside(cv::Point2d p, double margin) {
  return p.x >= margin && p.y >= margin && p.x <= kW - 1 - margin && p.y <= kH - 1 - margin;
}

cv::Point2d Pos(const Keypoint& kp) { return {kp.u, kp.v}; }

/// Share of view-1 keypoints (visible in view 2) with a view-2 keypoint within
/// 2 px * scale(level) of the true position.
double Repeatability(const FrameFeatures& f1, const FrameFeatures& f2, const cv::Matx33d& h,
                     const ScalePyramid& pyr) {
  int visible = 0, repeated = 0;
  for (const Keypoint& kp1 : f1.keypoints) {
    const cv::Point2d p = test::Apply(h, Pos(kp1));
    if (!Inside(p, 25)) continue;
    ++visible;
    const double tol = 2.0 * pyr.scale[kp1.level];
    for (const Keypoint& kp2 : f2.keypoints) {
      if (cv::norm(Pos(kp2) - p) <= tol) {
        ++repeated;
        break;
      }
    }
  }
  return visible > 0 ? static_cast<double>(repeated) / visible : 0.0;
}

struct MatchStats {
  int matches = 0, correct = 0;
  double median_angle_error_deg = 180;
};

/// Brute-force nearest neighbour, ratio 0.8, mutual; correct when within 3 px * scale of the
/// true position. Also the median error of the keypoint angle change against the true rotation.
MatchStats MatchAndCheck(const FrameFeatures& f1, const FrameFeatures& f2, const cv::Matx33d& h,
                         const ScalePyramid& pyr, double rotation_deg) {
  auto nearest = [](const OrbDescriptor& d, const FrameFeatures& f, int* second) {
    int best = -1, bd = 257, sd = 257;
    for (size_t j = 0; j < f.size(); ++j) {
      const int dist = HammingDistance(d, f.descriptors[j]);
      if (dist < bd) {
        sd = bd;
        bd = dist;
        best = static_cast<int>(j);
      } else if (dist < sd) {
        sd = dist;
      }
    }
    *second = sd;
    return std::make_pair(best, bd);
  };
  MatchStats stats;
  std::vector<double> angle_errors;
  for (size_t i = 0; i < f1.size(); ++i) {
    int second12 = 0, second21 = 0;
    const auto [j, d] = nearest(f1.descriptors[i], f2, &second12);
    if (j < 0 || d > 50 || d >= 0.8 * second12) continue;
    if (nearest(f2.descriptors[j], f1, &second21).first != static_cast<int>(i)) continue;
    ++stats.matches;
    const cv::Point2d p = test::Apply(h, Pos(f1.keypoints[i]));
    if (cv::norm(Pos(f2.keypoints[j]) - p) > 3.0 * pyr.scale[f1.keypoints[i].level]) continue;
    ++stats.correct;
    double e = f2.keypoints[j].angle_deg - f1.keypoints[i].angle_deg - rotation_deg;
    e = std::fmod(e + 540.0, 360.0) - 180.0;
    angle_errors.push_back(std::fabs(e));
  }
  if (!angle_errors.empty()) {
    std::nth_element(angle_errors.begin(), angle_errors.begin() + angle_errors.size() / 2,
                     angle_errors.end());
    stats.median_angle_error_deg = angle_errors[angle_errors.size() / 2];
  }
  return stats;
}

TEST(OrbExtractorOptions, ValidateCatchesBadValues) {
  OrbExtractorOptions o;
  EXPECT_EQ(o.Validate(), "");
  o.scale_factor = 1.0;
  EXPECT_NE(o.Validate(), "");
  o = OrbExtractorOptions{};
  o.min_fast_threshold = 30;
  EXPECT_NE(o.Validate(), "");
  o = OrbExtractorOptions{};
  o.edge_border_px = 10;
  EXPECT_NE(o.Validate(), "");
  o = OrbExtractorOptions{};
  o.num_levels = 0;
  EXPECT_NE(o.Validate(), "");
}

TEST(OrbExtractor, FeaturesPerLevelFollowGeometricSeries) {
  OrbExtractor ex{OrbExtractorOptions{}};
  const auto& n = ex.features_per_level();
  ASSERT_EQ(n.size(), 8u);
  int total = 0;
  for (size_t l = 0; l < n.size(); ++l) {
    total += n[l];
    if (l > 0 && l + 1 < n.size()) {
      EXPECT_NEAR(n[l], n[l - 1] / 1.2, 1.0);
    }
  }
  EXPECT_EQ(total, 1000);
  EXPECT_NEAR(ex.pyramid().scale[7], std::pow(1.2, 7), 1e-9);
}

TEST(OrbExtractor, FillsBudgetSpreadOverImageAndLevels) {
  OrbExtractor ex{OrbExtractorOptions{}};
  const cv::Mat img = test::MakeTexture(kW, kH, 3);
  const FrameFeatures f = ex.Extract(img);
  ASSERT_EQ(f.descriptors.size(), f.keypoints.size());
  EXPECT_GE(f.size(), 950u);
  EXPECT_LE(f.size(), 1000u);
  std::vector<int> cells(16, 0), levels(8, 0);
  for (const Keypoint& kp : f.keypoints) {
    // Inside the image with at least the edge border (19 px at level 0).
    EXPECT_GE(kp.u, 18.f);
    EXPECT_GE(kp.v, 18.f);
    EXPECT_LE(kp.u, kW - 19.f);
    EXPECT_LE(kp.v, kH - 19.f);
    EXPECT_GE(kp.angle_deg, 0.f);
    EXPECT_LT(kp.angle_deg, 360.f);
    ++cells[std::min(3, static_cast<int>(kp.v * 4 / kH)) * 4 +
            std::min(3, static_cast<int>(kp.u * 4 / kW))];
    ++levels[kp.level];
  }
  for (int c = 0; c < 16; ++c) EXPECT_GE(cells[c], 25) << "4x4 cell " << c;
  for (int l = 0; l < 8; ++l) {
    EXPECT_GE(levels[l], 0.8 * ex.features_per_level()[l]) << "level " << l;
  }
}

// Deterministic for a given image sequence: the adaptive FAST threshold carries state from
// one frame to the next, so two extractors fed the same frames agree frame by frame.
TEST(OrbExtractor, IsDeterministic) {
  OrbExtractor a{OrbExtractorOptions{}}, b{OrbExtractorOptions{}};
  const cv::Mat img = test::MakeTexture(kW, kH, 5);
  for (int frame = 0; frame < 3; ++frame) {
    const FrameFeatures fa = a.Extract(img), fb = b.Extract(img);
    ASSERT_EQ(fa.size(), fb.size());
    for (size_t i = 0; i < fa.size(); ++i) {
      EXPECT_EQ(fa.keypoints[i].u, fb.keypoints[i].u);
      EXPECT_EQ(fa.keypoints[i].v, fb.keypoints[i].v);
      EXPECT_EQ(fa.keypoints[i].angle_deg, fb.keypoints[i].angle_deg);
      EXPECT_EQ(fa.descriptors[i], fb.descriptors[i]);
    }
  }
  // With a fixed threshold, the same image gives the same features every time.
  OrbExtractorOptions fixed;
  fixed.adapt_high_ratio = 0.0;
  OrbExtractor c{fixed};
  const FrameFeatures f1 = c.Extract(img), f2 = c.Extract(img);
  ASSERT_EQ(f1.size(), f2.size());
  for (size_t i = 0; i < f1.size(); ++i) EXPECT_EQ(f1.descriptors[i], f2.descriptors[i]);
}

// Dense texture: the threshold rises over the first frames, the keypoint budget and the
// spread over the image stay (the point of adapting: fewer corners to score, same output).
TEST(OrbExtractor, AdaptiveThresholdKeepsCountAndCoverageOnDenseTexture) {
  const cv::Mat img = test::MakeTexture(kW, kH, 5);
  OrbExtractorOptions fixed;
  fixed.adapt_high_ratio = 0.0;
  OrbExtractor adaptive{OrbExtractorOptions{}}, reference{fixed};
  FrameFeatures fa;
  for (int frame = 0; frame < 20; ++frame) fa = adaptive.Extract(img);
  const FrameFeatures ff = reference.Extract(img);
  EXPECT_GT(adaptive.level_thresholds()[0], OrbExtractorOptions{}.ini_fast_threshold) << "never adapted";
  EXPECT_EQ(reference.level_thresholds()[0], OrbExtractorOptions{}.ini_fast_threshold);
  EXPECT_EQ(fa.size(), ff.size());
  auto occupied = [](const FrameFeatures& f) {
    std::vector<int> cells(8 * 5, 0);
    for (const auto& kp : f.keypoints) ++cells[std::min(4, static_cast<int>(kp.v * 5 / kH)) * 8 + std::min(7, static_cast<int>(kp.u * 8 / kW))];
    return std::count_if(cells.begin(), cells.end(), [](int c) { return c > 0; });
  };
  EXPECT_GE(occupied(fa), occupied(ff) - 1);
  // Some keypoints differ (stronger corners win), but most are the same.
  int same = 0;
  for (const auto& a : fa.keypoints) {
    for (const auto& b : ff.keypoints) {
      if (a.level == b.level && a.u == b.u && a.v == b.v) {
        ++same;
        break;
      }
    }
  }
  EXPECT_GT(same, static_cast<int>(fa.size()) / 3);
}

TEST(OrbExtractor, HandlesEmptySmallAndColourImages) {
  OrbExtractor ex{OrbExtractorOptions{}};
  EXPECT_EQ(ex.Extract(cv::Mat()).size(), 0u);
  EXPECT_EQ(ex.Extract(cv::Mat(30, 30, CV_8UC1, cv::Scalar(0))).size(), 0u);
  EXPECT_EQ(ex.Extract(cv::Mat(kH, kW, CV_8UC1, cv::Scalar(90))).size(), 0u);  // flat: no corners
  const cv::Mat grey = test::MakeTexture(kW, kH, 9);
  cv::Mat bgr;
  cv::merge(std::vector<cv::Mat>{grey, grey, grey}, bgr);
  EXPECT_EQ(ex.Extract(bgr).size(), ex.Extract(grey).size());
}

TEST(OrbExtractor, UniformBudgetOnCornerHeavyQuadrant) {
  // Texture only in the left half: the quadtree still gives keypoints everywhere there and
  // the budget is kept (the low threshold rescues weak cells).
  cv::Mat img = test::MakeTexture(kW, kH, 11);
  img(cv::Rect(kW / 2, 0, kW / 2, kH)).setTo(cv::Scalar(100));
  OrbExtractor ex{OrbExtractorOptions{}};
  const FrameFeatures f = ex.Extract(img);
  EXPECT_GE(f.size(), 900u);
  for (const Keypoint& kp : f.keypoints) EXPECT_LE(kp.u, kW / 2 + 10.f);
}

struct WarpCase {
  double angle_deg, scale, min_repeatability, min_correct_ratio;
  int min_correct;
};

class OrbUnderWarp : public ::testing::TestWithParam<WarpCase> {};

TEST_P(OrbUnderWarp, RepeatableAndMatchable) {
  const WarpCase c = GetParam();
  const ViewPair views = MakeViewPair(c.angle_deg, c.scale, 21);
  OrbExtractor ex{OrbExtractorOptions{}};
  const FrameFeatures f1 = ex.Extract(views.image1), f2 = ex.Extract(views.image2);
  const double rep = Repeatability(f1, f2, views.view2_from_view1, ex.pyramid());
  const MatchStats m = MatchAndCheck(f1, f2, views.view2_from_view1, ex.pyramid(), c.angle_deg);
  const double ratio = m.matches > 0 ? static_cast<double>(m.correct) / m.matches : 0.0;
  std::printf(
      "angle %.0f scale %.2f: repeatability %.3f, matches %d, correct %d (%.3f), "
      "median angle error %.2f deg\n",
      c.angle_deg, c.scale, rep, m.matches, m.correct, ratio, m.median_angle_error_deg);
  EXPECT_GE(rep, c.min_repeatability);
  EXPECT_GE(m.correct, c.min_correct);
  EXPECT_GE(ratio, c.min_correct_ratio);
  EXPECT_LE(m.median_angle_error_deg, 3.0);
}

// Measured (seed 21): 30 deg: repeatability 0.78, 278/286 correct; zoom 1.2: 0.88,
// 294/308 correct;
// 15 deg + zoom 1.5: 0.87, 159/186. Bounds leave room for platform differences in OpenCV's
// warp and resize.
INSTANTIATE_TEST_SUITE_P(Warps, OrbUnderWarp,
                         ::testing::Values(WarpCase{0, 1.0, 0.95, 0.98, 800},
                                           WarpCase{30, 1.0, 0.6, 0.9, 200},
                                           WarpCase{0, 1.2, 0.7, 0.9, 200},
                                           WarpCase{15, 1.5, 0.65, 0.8, 100}));

TEST(KeypointGrid, MatchesBruteForce) {
  OrbExtractor ex{OrbExtractorOptions{}};
  const FrameFeatures f = ex.Extract(test::MakeTexture(kW, kH, 4));
  const KeypointGrid grid(f, kW, kH);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-20.f, kW + 20.f), v(-20.f, kH + 20.f), r(0.f, 60.f);
  std::uniform_int_distribution<int> lvl(0, 7);
  for (int q = 0; q < 300; ++q) {
    const float qu = u(rng), qv = v(rng), qr = r(rng);
    int lo = lvl(rng), hi = lvl(rng);
    if (q % 3 == 0) hi = -1;
    std::vector<int> expected;
    for (int i = 0; i < static_cast<int>(f.size()); ++i) {
      const Keypoint& kp = f.keypoints[i];
      if (kp.level < lo || (hi >= 0 && kp.level > hi)) continue;
      if (std::fabs(kp.u - qu) <= qr && std::fabs(kp.v - qv) <= qr) expected.push_back(i);
    }
    EXPECT_EQ(grid.FeaturesInArea(qu, qv, qr, lo, hi), expected) << "query " << q;
  }
  EXPECT_TRUE(KeypointGrid().FeaturesInArea(10, 10, 5).empty());
}

TEST(SteeredBrief, RotatingThePatchRotatesTheAngle) {
  // A single patch rotated by 90 degrees exactly (no interpolation): the angle follows and the
  // descriptor is almost the same.
  const cv::Mat tex = test::MakeTexture(101, 101, 13);
  cv::Mat rot;
  cv::rotate(tex, rot, cv::ROTATE_90_CLOCKWISE);  // image y down: +90 deg in our angle
  const float a0 = IntensityCentroidAngle(tex, 50, 50);
  const float a1 = IntensityCentroidAngle(rot, 50, 50);
  double diff = std::fmod(a1 - a0 + 720.0, 360.0);
  EXPECT_NEAR(diff, 90.0, 0.5);
  EXPECT_LE(HammingDistance(SteeredBrief(tex, 50, 50, a0), SteeredBrief(rot, 50, 50, a1)), 40);
}

}  // namespace
}  // namespace ccm
