#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "slam_core/io/video_source.h"

namespace ccm {
namespace {

CameraIntrinsics Calib(int w, int h) {
  CameraIntrinsics c;
  c.width_px = w;
  c.height_px = h;
  c.fx = c.fy = 300;
  c.cx = w / 2.0;
  c.cy = h / 2.0;
  return c;
}

// Writes an MJPG AVI (OpenCV's built-in encoder) with a moving bright square.
std::string WriteVideo(int frames, int w, int h) {
  const std::string path = ::testing::TempDir() + "/ccm_video_source_test.avi";
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0, cv::Size(w, h), true);
  EXPECT_TRUE(writer.isOpened());
  for (int i = 0; i < frames; ++i) {
    cv::Mat img(h, w, CV_8UC3, cv::Scalar(30, 30, 30));
    cv::rectangle(img, cv::Rect(10 + 5 * i, 20, 20, 20), cv::Scalar(255, 255, 255), cv::FILLED);
    writer.write(img);
  }
  return path;
}

TEST(VideoSource, ReadsAFileAsGrayFramesWithRateStamps) {
  const std::string path = WriteVideo(12, 160, 120);
  IoStatus status;
  auto source = VideoSource::Open(path, Calib(160, 120), &status);
  ASSERT_NE(source, nullptr) << status.message();
  int n = 0;
  int64_t first = 0;
  while (auto f = source->Next()) {
    ASSERT_EQ(f->image.type(), CV_8UC1);
    ASSERT_EQ(f->image.cols, 160);
    if (n == 0) first = f->stamp_ns;
    // The square moves 5 px per frame: its brightest column tracks that.
    cv::Mat row = f->image.row(30);
    double max_value;
    cv::Point max_loc;
    cv::minMaxLoc(row, nullptr, &max_value, nullptr, &max_loc);
    EXPECT_NEAR(max_loc.x, 10 + 5 * n, 3) << "frame " << n;
    EXPECT_EQ(f->stamp_ns - first, static_cast<int64_t>(1e9 * n / 10.0));
    ++n;
  }
  EXPECT_EQ(n, 12);
  EXPECT_EQ(source->error(), "");
}

TEST(VideoSource, RejectsMissingInputAndWrongCalibrationSize) {
  IoStatus status;
  EXPECT_EQ(VideoSource::Open("/nonexistent/video.avi", Calib(160, 120), &status), nullptr);
  EXPECT_NE(status.message().find("cannot open"), std::string::npos);
  const std::string path = WriteVideo(3, 160, 120);
  EXPECT_EQ(VideoSource::Open(path, Calib(640, 480), &status), nullptr);
  EXPECT_NE(status.message().find("160x120"), std::string::npos) << status.message();
}

}  // namespace
}  // namespace ccm
