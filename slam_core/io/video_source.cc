#include "slam_core/io/video_source.h"

#include <chrono>
#include <filesystem>

#include <opencv2/imgproc.hpp>

namespace ccm {

cv::Mat GrayFromCapture(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return gray;
}

std::unique_ptr<VideoSource> VideoSource::Open(const std::string& device_or_file, const CameraIntrinsics& intrinsics,
                                               IoStatus* status) {
  std::unique_ptr<VideoSource> s(new VideoSource());
  s->intrinsics_ = intrinsics;
  s->name_ = device_or_file;
  const bool is_index = IsCameraIndex(device_or_file);
  s->is_file_ = !is_index && std::filesystem::is_regular_file(device_or_file);
  if (!is_index && !std::filesystem::exists(device_or_file)) {
    // Checked here so OpenCV's backends do not print their own failure chatter first.
    *status = IoStatus::Error(device_or_file + ": cannot open camera or video (no such file or device)");
    return nullptr;
  }
  const bool opened = is_index ? s->capture_.open(std::stoi(device_or_file)) : s->capture_.open(device_or_file);
  if (!opened || !s->capture_.isOpened()) {
    *status = IoStatus::Error(device_or_file + ": cannot open camera or video");
    return nullptr;
  }
  const int w = static_cast<int>(s->capture_.get(cv::CAP_PROP_FRAME_WIDTH));
  const int h = static_cast<int>(s->capture_.get(cv::CAP_PROP_FRAME_HEIGHT));
  if (w > 0 && h > 0 && (w != intrinsics.width_px || h != intrinsics.height_px)) {
    *status = IoStatus::Error(device_or_file + ": delivers " + std::to_string(w) + "x" + std::to_string(h) +
                              " but the calibration is for " + std::to_string(intrinsics.width_px) + "x" +
                              std::to_string(intrinsics.height_px));
    return nullptr;
  }
  const double fps = s->capture_.get(cv::CAP_PROP_FPS);
  if (fps > 0) s->fps_ = fps;
  if (s->is_file_) {
    const double n = s->capture_.get(cv::CAP_PROP_FRAME_COUNT);
    if (n > 0) s->size_ = static_cast<int64_t>(n);
  }
  s->start_ns_ = std::chrono::duration_cast<std::chrono::nanoseconds>(
                     std::chrono::system_clock::now().time_since_epoch())
                     .count();
  *status = IoStatus::Ok();
  return s;
}

std::optional<Frame> VideoSource::Next() {
  cv::Mat image;
  if (!capture_.read(image) || image.empty()) {
    if (!is_file_) error_ = name_ + ": camera stopped delivering frames";
    return std::nullopt;
  }
  Frame f;
  f.image = GrayFromCapture(image);
  // Files: stamps from the frame rate (repeatable). Devices: wall clock at capture.
  f.stamp_ns = is_file_ ? start_ns_ + static_cast<int64_t>(1e9 * index_ / fps_)
                        : std::chrono::duration_cast<std::chrono::nanoseconds>(
                              std::chrono::system_clock::now().time_since_epoch())
                              .count();
  f.source_name = name_ + ":" + std::to_string(index_++);
  return f;
}

}  // namespace ccm
