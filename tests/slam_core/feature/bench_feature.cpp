// bench_feature: ORB extraction cost per frame on one core, keypoints per level and spatial
// coverage, with the fixed FAST threshold (ORB-SLAM's 20/7) and with the adaptive one (the
// default). A plain program printing numbers (not a ctest test).
// Usage: bench_feature [image_path] [iterations]
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "slam_core/feature/orb_extractor.h"
#include "synthetic_image.h"

namespace {

void Run(const char* name, ccm::OrbExtractorOptions options, const cv::Mat& image, int iterations) {
  ccm::OrbExtractor extractor{options};
  ccm::FrameFeatures features;
  // Warm-up; also lets the adaptive threshold settle as it would over a video's first frames.
  for (int i = 0; i < 30; ++i) features = extractor.Extract(image);
  std::vector<double> ms;
  const std::clock_t cpu0 = std::clock();
  for (int i = 0; i < iterations; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    features = extractor.Extract(image);
    const auto t1 = std::chrono::steady_clock::now();
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
  }
  // Process CPU time is less disturbed than wall time when other jobs share the cores.
  const double cpu_ms = 1000.0 * (std::clock() - cpu0) / CLOCKS_PER_SEC / iterations;
  std::sort(ms.begin(), ms.end());
  std::printf("%s FAST threshold:\n", name);
  std::printf("  extract ms/frame: median %.2f  p90 %.2f  min %.2f  (CPU %.2f)\n", ms[ms.size() / 2],
              ms[ms.size() * 9 / 10], ms.front(), cpu_ms);
  std::printf("  keypoints: %zu (target %d)\n", features.size(), extractor.options().num_features);
  std::vector<int> per_level(extractor.options().num_levels, 0);
  for (const auto& kp : features.keypoints) ++per_level[kp.level];
  std::printf("  per level (found / target):");
  for (size_t l = 0; l < per_level.size(); ++l) std::printf(" %d/%d", per_level[l], extractor.features_per_level()[l]);
  std::printf("\n");
  // Coverage: share of 16x10 cells holding at least one keypoint, and the emptiest and
  // fullest cell of a 4x4 grid.
  constexpr int kCx = 16, kCy = 10;
  std::vector<int> fine(kCx * kCy, 0), coarse(16, 0);
  for (const auto& kp : features.keypoints) {
    ++fine[std::min(kCy - 1, static_cast<int>(kp.v * kCy / image.rows)) * kCx +
           std::min(kCx - 1, static_cast<int>(kp.u * kCx / image.cols))];
    ++coarse[std::min(3, static_cast<int>(kp.v * 4 / image.rows)) * 4 + std::min(3, static_cast<int>(kp.u * 4 / image.cols))];
  }
  const int occupied = static_cast<int>(std::count_if(fine.begin(), fine.end(), [](int c) { return c > 0; }));
  std::printf("  coverage: %d/%d cells of %dx%d occupied; 4x4 grid min %d max %d per cell\n", occupied, kCx * kCy, kCx,
              kCy, *std::min_element(coarse.begin(), coarse.end()), *std::max_element(coarse.begin(), coarse.end()));
}

}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(1);  // "one core": OpenCV must not spread the blur/resize over threads
  cv::Mat image;
  if (argc > 1) {
    image = cv::imread(argv[1], cv::IMREAD_GRAYSCALE);
    if (image.empty()) {
      std::fprintf(stderr, "cannot read %s\n", argv[1]);
      return 1;
    }
  } else {
    image = ccm::test::MakeTexture(752, 480, 7);
  }
  const int iterations = argc > 2 ? std::max(1, std::atoi(argv[2])) : 200;
  std::printf("image %dx%d, %d iterations, 1 thread\n", image.cols, image.rows, iterations);
  ccm::OrbExtractorOptions fixed;
  fixed.adapt_high_ratio = 0.0;
  Run("fixed", fixed, image, iterations);
  Run("adaptive", ccm::OrbExtractorOptions{}, image, iterations);
  return 0;
}
