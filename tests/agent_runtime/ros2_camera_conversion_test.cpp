// ccm_agent --ros2-image's conversion layer: sensor_msgs/Image in every accepted encoding (and
// padded rows) gives the exact gray image; refusals name what was wrong; CameraInfo's K, D,
// binning and region of interest give the calibration REP 104 defines.
#include "agent_runtime/ros2_camera_conversion.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cstring>

#include "agent_runtime/ros2_camera_source.h"

namespace ccm::agent {
namespace {

using sensor_msgs::msg::dds_::CameraInfo_;
using sensor_msgs::msg::dds_::Image_;

cv::Mat Pattern(int w, int h) {
  cv::Mat m(h, w, CV_8UC1);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) m.at<uint8_t>(r, c) = static_cast<uint8_t>((r * 7 + c * 13) % 251);
  }
  return m;
}

Image_ ToMsg(const cv::Mat& m, const std::string& encoding, int pad) {
  Image_ img;
  img.width(m.cols);
  img.height(m.rows);
  img.encoding(encoding);
  const size_t row = m.cols * m.elemSize();
  img.step(static_cast<uint32_t>(row + pad));
  img.data().assign(img.step() * m.rows, 0xAB);  // padding bytes that must not leak in
  for (int r = 0; r < m.rows; ++r) std::memcpy(img.data().data() + r * img.step(), m.ptr(r), row);
  return img;
}

TEST(Ros2CameraConversion, EveryAcceptedEncodingGivesTheExactGrayImage) {
  const cv::Mat gray = Pattern(37, 11);
  cv::Mat colour(gray.size(), CV_8UC3), rgba;
  // Distinct channels, so a swapped R and B would give another gray.
  for (int r = 0; r < gray.rows; ++r) {
    for (int c = 0; c < gray.cols; ++c) colour.at<cv::Vec3b>(r, c) = {uint8_t(c * 5), uint8_t(r * 9), uint8_t(r + c)};
  }
  cv::cvtColor(colour, rgba, cv::COLOR_BGR2BGRA);
  cv::Mat expected_bgr, expected_rgb, out;
  cv::cvtColor(colour, expected_bgr, cv::COLOR_BGR2GRAY);
  cv::cvtColor(colour, expected_rgb, cv::COLOR_RGB2GRAY);
  std::string error;
  for (const int pad : {0, 3}) {
    ASSERT_TRUE(Ros2ImageToGray(ToMsg(gray, "mono8", pad), &out, &error)) << error;
    EXPECT_EQ(cv::norm(out, gray, cv::NORM_INF), 0) << "mono8 pad " << pad;
    ASSERT_TRUE(Ros2ImageToGray(ToMsg(gray, "8UC1", pad), &out, &error)) << error;
    EXPECT_EQ(cv::norm(out, gray, cv::NORM_INF), 0);
    ASSERT_TRUE(Ros2ImageToGray(ToMsg(colour, "bgr8", pad), &out, &error)) << error;
    EXPECT_EQ(cv::norm(out, expected_bgr, cv::NORM_INF), 0) << "bgr8 pad " << pad;
    ASSERT_TRUE(Ros2ImageToGray(ToMsg(colour, "rgb8", pad), &out, &error)) << error;
    EXPECT_EQ(cv::norm(out, expected_rgb, cv::NORM_INF), 0) << "rgb8 pad " << pad;
    ASSERT_TRUE(Ros2ImageToGray(ToMsg(rgba, "bgra8", pad), &out, &error)) << error;
    EXPECT_EQ(cv::norm(out, expected_bgr, cv::NORM_INF), 0);
    ASSERT_TRUE(Ros2ImageToGray(ToMsg(rgba, "rgba8", pad), &out, &error)) << error;
    EXPECT_EQ(cv::norm(out, expected_rgb, cv::NORM_INF), 0);
  }
  EXPECT_NE(expected_bgr.at<uint8_t>(5, 20), expected_rgb.at<uint8_t>(5, 20));  // the test can tell them apart
  // A gray image sent as bgr8 (equal channels) comes back unchanged.
  cv::Mat grey3;
  cv::cvtColor(gray, grey3, cv::COLOR_GRAY2BGR);
  ASSERT_TRUE(Ros2ImageToGray(ToMsg(grey3, "bgr8", 0), &out, &error));
  EXPECT_EQ(cv::norm(out, gray, cv::NORM_INF), 0);
}

TEST(Ros2CameraConversion, MalformedImagesAreRefusedWithTheReason) {
  const cv::Mat gray = Pattern(16, 8);
  cv::Mat out;
  std::string error;
  Image_ yuv = ToMsg(gray, "mono8", 0);
  yuv.encoding("yuv422");
  EXPECT_FALSE(Ros2ImageToGray(yuv, &out, &error));
  EXPECT_NE(error.find("'yuv422' is not supported"), std::string::npos) << error;
  EXPECT_NE(error.find("mono8"), std::string::npos) << error;
  Image_ bayer = ToMsg(gray, "mono8", 0);
  bayer.encoding("bayer_rggb8");
  EXPECT_FALSE(Ros2ImageToGray(bayer, &out, &error));
  Image_ short_step = ToMsg(gray, "mono8", 0);
  short_step.step(15);
  EXPECT_FALSE(Ros2ImageToGray(short_step, &out, &error));
  EXPECT_NE(error.find("shorter than a row"), std::string::npos) << error;
  Image_ short_data = ToMsg(gray, "mono8", 0);
  short_data.data().resize(16 * 8 - 1);
  EXPECT_FALSE(Ros2ImageToGray(short_data, &out, &error));
  EXPECT_NE(error.find("127 bytes"), std::string::npos) << error;
  Image_ empty;
  empty.encoding("mono8");
  EXPECT_FALSE(Ros2ImageToGray(empty, &out, &error));
  Image_ huge = ToMsg(gray, "mono8", 0);
  huge.width(1u << 20);  // would need 1 MiB per row that is not there
  EXPECT_FALSE(Ros2ImageToGray(huge, &out, &error));
}

CameraInfo_ Info(const std::string& model, std::vector<double> d) {
  CameraInfo_ info;
  info.width(752);
  info.height(480);
  info.distortion_model(model);
  info.d(std::move(d));
  info.k({458.654, 0, 367.215, 0, 457.296, 248.375, 0, 0, 1});
  return info;
}

TEST(Ros2CameraConversion, CameraInfoGivesTheCalibration) {
  CameraIntrinsics c;
  std::string error;
  ASSERT_TRUE(Ros2CameraInfoToIntrinsics(Info("plumb_bob", {-0.28, 0.07, 1e-4, 2e-5, 0.0}), &c, &error)) << error;
  EXPECT_EQ(c.type, CameraType::kPinholeRadTan);
  EXPECT_EQ(c.width_px, 752);
  EXPECT_EQ(c.height_px, 480);
  EXPECT_DOUBLE_EQ(c.fx, 458.654);
  EXPECT_DOUBLE_EQ(c.fy, 457.296);
  EXPECT_DOUBLE_EQ(c.cx, 367.215);
  EXPECT_DOUBLE_EQ(c.cy, 248.375);
  EXPECT_EQ(c.distortion, (std::vector<double>{-0.28, 0.07, 1e-4, 2e-5, 0.0}));
  ASSERT_TRUE(Ros2CameraInfoToIntrinsics(Info("rational_polynomial", {-0.28, 0.07, 1e-4, 2e-5, 0.01, 0, 0, 0}), &c,
                                         &error)) << error;
  EXPECT_EQ(c.distortion.size(), 5u);
  ASSERT_TRUE(Ros2CameraInfoToIntrinsics(Info("equidistant", {0.01, -0.002, 0.001, 0.0}), &c, &error)) << error;
  EXPECT_EQ(c.type, CameraType::kFisheyeEquidistant);
  ASSERT_TRUE(Ros2CameraInfoToIntrinsics(Info("", {}), &c, &error)) << error;  // uncalibrated distortion: none
  EXPECT_TRUE(c.distortion.empty());
  // REP 104: binning 2 and a region of interest at (100, 40) of 400x320 full-resolution pixels.
  CameraInfo_ binned = Info("plumb_bob", {0, 0, 0, 0, 0});
  binned.binning_x(2);
  binned.binning_y(2);
  binned.roi().x_offset(100);
  binned.roi().y_offset(40);
  binned.roi().width(400);
  binned.roi().height(320);
  ASSERT_TRUE(Ros2CameraInfoToIntrinsics(binned, &c, &error)) << error;
  EXPECT_EQ(c.width_px, 200);
  EXPECT_EQ(c.height_px, 160);
  EXPECT_DOUBLE_EQ(c.fx, 458.654 / 2);
  EXPECT_DOUBLE_EQ(c.cx, (367.215 - 100) / 2);
  EXPECT_DOUBLE_EQ(c.cy, (248.375 - 40) / 2);
}

TEST(Ros2CameraConversion, UnusableCameraInfoIsRefusedWithTheReason) {
  CameraIntrinsics c;
  std::string error;
  EXPECT_FALSE(Ros2CameraInfoToIntrinsics(Info("kannala_brandt", {0, 0, 0, 0}), &c, &error));
  EXPECT_NE(error.find("'kannala_brandt' is not supported"), std::string::npos) << error;
  EXPECT_FALSE(Ros2CameraInfoToIntrinsics(Info("rational_polynomial", {0, 0, 0, 0, 0, 0.1, 0, 0}), &c, &error));
  EXPECT_NE(error.find("k4..k6"), std::string::npos) << error;
  EXPECT_FALSE(Ros2CameraInfoToIntrinsics(Info("plumb_bob", {0, 0}), &c, &error));
  EXPECT_FALSE(Ros2CameraInfoToIntrinsics(Info("equidistant", {0, 0, 0, 0, 0}), &c, &error));
  CameraInfo_ uncalibrated = Info("", {});
  uncalibrated.k({0, 0, 0, 0, 0, 0, 0, 0, 0});  // what drivers publish without a calibration file
  EXPECT_FALSE(Ros2CameraInfoToIntrinsics(uncalibrated, &c, &error));
  EXPECT_NE(error.find("--calibration"), std::string::npos) << error;
}

TEST(Ros2CameraConversion, TopicNamesFollowRos2AndImageTransport) {
  EXPECT_EQ(CameraInfoTopicFor("/camera/image_raw"), "/camera/camera_info");
  EXPECT_EQ(CameraInfoTopicFor("/drone1/cam/image"), "/drone1/cam/camera_info");
  EXPECT_EQ(CameraInfoTopicFor("image"), "camera_info");
  builtin_interfaces::msg::dds_::Time_ t;
  t.sec(1700000000);
  t.nanosec(123456789);
  EXPECT_EQ(Ros2StampNs(t), 1700000000123456789LL);
  Ros2CameraOptions o;
  o.image_topic = "/camera/image raw";
  EXPECT_NE(o.Validate().find("--ros2-image"), std::string::npos);
  o.image_topic = "/camera/image_raw";
  EXPECT_EQ(o.Validate(), "");
  o.domain_id = 233;
  EXPECT_NE(o.Validate().find("0..232"), std::string::npos);
}

}  // namespace
}  // namespace ccm::agent
