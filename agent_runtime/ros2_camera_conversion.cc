#include "agent_runtime/ros2_camera_conversion.h"

#include <opencv2/imgproc.hpp>

#include <cmath>

namespace ccm::agent {
namespace {

// Larger than any camera a drone carries; bounds what a malformed message can make us allocate.
constexpr uint32_t kMaxSidePx = 16384;

// Channels of an accepted encoding and the conversion to gray (-1: none needed); 0 channels
// for an encoding we do not take.
struct Encoding {
  int channels = 0;
  int to_gray = -1;
};

Encoding EncodingOf(const std::string& name) {
  if (name == "mono8" || name == "8UC1") return {1, -1};
  if (name == "bgr8") return {3, cv::COLOR_BGR2GRAY};
  if (name == "rgb8") return {3, cv::COLOR_RGB2GRAY};
  if (name == "bgra8") return {4, cv::COLOR_BGRA2GRAY};
  if (name == "rgba8") return {4, cv::COLOR_RGBA2GRAY};
  return {};
}

std::string Size(uint32_t w, uint32_t h) { return std::to_string(w) + "x" + std::to_string(h); }

}  // namespace

int64_t Ros2StampNs(const builtin_interfaces::msg::dds_::Time_& stamp) {
  return static_cast<int64_t>(stamp.sec()) * 1000000000 + static_cast<int64_t>(stamp.nanosec());
}

bool Ros2ImageToGray(const sensor_msgs::msg::dds_::Image_& image, cv::Mat* gray, std::string* error) {
  const Encoding enc = EncodingOf(image.encoding());
  if (enc.channels == 0) {
    *error = "image encoding '" + image.encoding() + "' is not supported: publish one of " + kRos2ImageEncodings +
             " (a Bayer or YUV camera needs a debayer / image_proc node in front)";
    return false;
  }
  const uint32_t w = image.width(), h = image.height();
  if (w == 0 || h == 0 || w > kMaxSidePx || h > kMaxSidePx) {
    *error = "image of " + Size(w, h) + " pixels";
    return false;
  }
  const uint64_t row_bytes = static_cast<uint64_t>(w) * enc.channels;
  if (image.step() < row_bytes) {
    *error = "image step " + std::to_string(image.step()) + " is shorter than a row of " + Size(w, h) + " " +
             image.encoding() + " (" + std::to_string(row_bytes) + " bytes)";
    return false;
  }
  const uint64_t needed = static_cast<uint64_t>(image.step()) * h;
  if (image.data().size() < needed) {
    *error = "image data has " + std::to_string(image.data().size()) + " bytes, step x height is " +
             std::to_string(needed);
    return false;
  }
  // A view of the message's bytes; both branches below copy out of it.
  const cv::Mat view(static_cast<int>(h), static_cast<int>(w), CV_8UC(enc.channels),
                     const_cast<uint8_t*>(image.data().data()), image.step());
  if (enc.to_gray < 0) {
    *gray = view.clone();
  } else {
    cv::cvtColor(view, *gray, enc.to_gray);
  }
  return true;
}

bool Ros2CameraInfoToIntrinsics(const sensor_msgs::msg::dds_::CameraInfo_& info, CameraIntrinsics* intrinsics,
                                std::string* error) {
  const auto& k = info.k();
  const auto& d = info.d();
  const std::string& model = info.distortion_model();
  CameraIntrinsics c;
  if (model == "plumb_bob" || model == "rational_polynomial" || (model.empty() && d.empty())) {
    c.type = CameraType::kPinholeRadTan;
    const size_t expected = model == "rational_polynomial" ? 8 : model == "plumb_bob" ? 5 : 0;
    if (d.size() != expected && !(model == "plumb_bob" && d.size() == 4)) {
      *error = "camera info: distortion model '" + model + "' with " + std::to_string(d.size()) +
               " coefficients (expected " + std::to_string(expected) + ")";
      return false;
    }
    if (expected == 8 && (d[5] != 0.0 || d[6] != 0.0 || d[7] != 0.0)) {
      *error = "camera info: rational_polynomial with k4..k6 not 0 is not supported (radial-tangential k1 k2 p1 p2 "
               "k3 and equidistant are); recalibrate with plumb_bob or give --calibration FILE.yaml";
      return false;
    }
    c.distortion.assign(d.begin(), d.begin() + std::min<size_t>(d.size(), 5));
  } else if (model == "equidistant") {
    c.type = CameraType::kFisheyeEquidistant;
    if (d.size() != 4) {
      *error = "camera info: equidistant with " + std::to_string(d.size()) + " coefficients (expected k1 k2 k3 k4)";
      return false;
    }
    c.distortion.assign(d.begin(), d.end());
  } else {
    *error = "camera info: distortion model '" + model +
             "' is not supported (plumb_bob, rational_polynomial with k4..k6 = 0, equidistant); give --calibration "
             "FILE.yaml instead";
    return false;
  }
  // REP 104: K is for the full-resolution sensor; the published image is the region of
  // interest (all zero: the whole sensor) divided by the binning (0 means 1).
  const double bx = info.binning_x() > 1 ? info.binning_x() : 1.0;
  const double by = info.binning_y() > 1 ? info.binning_y() : 1.0;
  const auto& roi = info.roi();
  const bool has_roi = roi.width() > 0 && roi.height() > 0;
  const double full_w = has_roi ? roi.width() : info.width();
  const double full_h = has_roi ? roi.height() : info.height();
  c.width_px = static_cast<int>(full_w / bx);
  c.height_px = static_cast<int>(full_h / by);
  c.fx = k[0] / bx;
  c.fy = k[4] / by;
  c.cx = (k[2] - (has_roi ? roi.x_offset() : 0)) / bx;
  c.cy = (k[5] - (has_roi ? roi.y_offset() : 0)) / by;
  if (const std::string problem = ValidateIntrinsics(c); !problem.empty()) {
    *error = "camera info (" + Size(info.width(), info.height()) + ", K = [" + std::to_string(k[0]) + " 0 " +
             std::to_string(k[2]) + "; 0 " + std::to_string(k[4]) + " " + std::to_string(k[5]) +
             "]) is not a usable calibration: " + problem + " (is the camera calibrated? else give --calibration FILE.yaml)";
    return false;
  }
  *intrinsics = c;
  return true;
}

}  // namespace ccm::agent
