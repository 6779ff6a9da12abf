// bench_feature: ORB extraction cost per 752x480 frame on one core, keypoints per level and
// spatial coverage. A plain program printing numbers (not a ctest test).
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
  ccm::OrbExtractor extractor{ccm::OrbExtractorOptions{}};
  ccm::FrameFeatures features = extractor.Extract(image);  // warm-up
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
  double mean = 0;
  for (double m : ms) mean += m;
  mean /= ms.size();
  std::printf("image %dx%d, %d iterations, 1 thread\n", image.cols, image.rows, iterations);
  std::printf("extract ms/frame: mean %.2f  median %.2f  p90 %.2f  min %.2f\n", mean,
              ms[ms.size() / 2], ms[ms.size() * 9 / 10], ms.front());
  std::printf("extract CPU ms/frame: %.2f\n", cpu_ms);
  std::printf("keypoints: %zu (target %d)\n", features.size(), extractor.options().num_features);
  std::vector<int> per_level(extractor.options().num_levels, 0);
  for (const auto& kp : features.keypoints) ++per_level[kp.level];
  std::printf("per level (found / target):");
  for (size_t l = 0; l < per_level.size(); ++l) {
    std::printf(" %d/%d", per_level[l], extractor.features_per_level()[l]);
  }
  std::printf("\n");
  // Coverage: share of 16x10 cells (47 px squares) holding at least one keypoint, and the
  // emptiest cell of a 4x4 grid.
  constexpr int kCx = 16, kCy = 10;
  std::vector<int> fine(kCx * kCy, 0), coarse(16, 0);
  for (const auto& kp : features.keypoints) {
    const int fx = std::min(kCx - 1, static_cast<int>(kp.u * kCx / image.cols));
    const int fy = std::min(kCy - 1, static_cast<int>(kp.v * kCy / image.rows));
    ++fine[fy * kCx + fx];
    const int cx = std::min(3, static_cast<int>(kp.u * 4 / image.cols));
    const int cy = std::min(3, static_cast<int>(kp.v * 4 / image.rows));
    ++coarse[cy * 4 + cx];
  }
  const int occupied =
      static_cast<int>(std::count_if(fine.begin(), fine.end(), [](int c) { return c > 0; }));
  std::printf("coverage: %d/%d cells of %dx%d occupied; 4x4 grid min %d max %d per cell\n",
              occupied, kCx * kCy, kCx, kCy, *std::min_element(coarse.begin(), coarse.end()),
              *std::max_element(coarse.begin(), coarse.end()));
  return 0;
}
