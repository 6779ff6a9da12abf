// Live cameras and video files as a FrameSource, through OpenCV's VideoCapture (V4L2
// devices by index or path, or any file OpenCV can decode). The calibration comes from a
// YAML file (ReadCalibrationYaml) because a video carries none. Frames are converted to
// 8-bit gray; stamps come from the capture clock (devices) or the frame rate (files).
#pragma once

#include <memory>
#include <string>

#include <opencv2/videoio.hpp>

#include "slam_core/io/frame_source.h"
#include "slam_core/io/io_status.h"

namespace ccm {

/// "0", "1", ...: a camera by index (V4L2), not a path.
inline bool IsCameraIndex(const std::string& input) {
  return !input.empty() && input.find_first_not_of("0123456789") == std::string::npos;
}
/// A captured frame (gray, BGR or BGRA, as OpenCV's backends deliver) as 8-bit gray.
cv::Mat GrayFromCapture(const cv::Mat& image);

class VideoSource : public FrameSource {
 public:
  /// `device_or_file`: "0", "/dev/video0" or a video file path. nullptr + status on failure
  /// (unopenable input, image size different from the calibration).
  static std::unique_ptr<VideoSource> Open(const std::string& device_or_file, const CameraIntrinsics& intrinsics,
                                           IoStatus* status);

  std::optional<Frame> Next() override;
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  int64_t size() const override { return size_; }
  const std::string& error() const override { return error_; }
  bool live() const override { return !is_file_; }

 private:
  VideoSource() = default;

  cv::VideoCapture capture_;
  CameraIntrinsics intrinsics_;
  std::string name_;
  bool is_file_ = false;
  double fps_ = 30.0;
  int64_t size_ = -1;
  int64_t index_ = 0;
  int64_t start_ns_ = 0;
  std::string error_;
};

}  // namespace ccm
