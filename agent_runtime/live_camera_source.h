// ccm_agent --video DEVICE|PIPELINE (issue 29): a live camera as a FrameSource that behaves as a
// camera does in flight. A capture thread, owned here (started by Create, joined by the
// destructor), grabs frames as fast as the camera delivers them and keeps the newest `queue`;
// the tracker takes them in Next() and what it was too busy for is skipped and counted. A
// camera that stalls is reported once per stall; one that disappears (read fails: unplugged,
// a pipeline at its end, a driver crash) is reported and reopened every reopen_s, while the
// tracker waits and the VO keeps its map. Video files stay with slam_core's VideoSource
// (repeatable stamps, no thread).
//
// Grabbers: OpenCV's VideoCapture on a V4L2 index ("0") or device (/dev/video0), or a
// GStreamer pipeline (a string with " ! ", ending in appsink). Tests inject their own.
// Lock order: none nested (mutex_ alone; the grabber is touched by the capture thread only).
#pragma once

#include <opencv2/core.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "slam_core/io/frame_source.h"

namespace ccm::agent {

/// One camera's frames; used by the capture thread only.
class FrameGrabber {
 public:
  virtual ~FrameGrabber() = default;
  virtual bool Open() = 0;
  /// The next frame (blocks until the camera delivers one); false when the camera is gone.
  virtual bool Read(cv::Mat* image) = 0;
  virtual void Close() = 0;
};

/// OpenCV's VideoCapture on "0", "/dev/video0" or a GStreamer pipeline ("... ! appsink").
std::unique_ptr<FrameGrabber> MakeOpenCvGrabber(const std::string& device_or_pipeline);
/// A GStreamer pipeline rather than a device.
bool IsGStreamerPipeline(const std::string& input);

struct LiveCameraOptions {
  std::string name;             ///< for messages
  size_t queue = 1;             ///< newest frames kept for the tracker
  double stall_s = 2.0;         ///< silence reported as a stalled camera
  double reopen_s = 1.0;        ///< a camera that disappeared is reopened this often
  double end_after_s = 0.0;     ///< > 0: silence after which the flight ends
  const volatile bool* stop = nullptr;
};

class LiveCameraSource : public FrameSource {
 public:
  /// Opens the grabber once (nullptr and *error if that fails: a wrong device or pipeline is
  /// bad input, not a camera that went away) and starts the capture thread.
  static std::unique_ptr<LiveCameraSource> Create(std::unique_ptr<FrameGrabber> grabber,
                                                  const CameraIntrinsics& intrinsics,
                                                  const LiveCameraOptions& options, std::string* error);
  ~LiveCameraSource() override;

  std::optional<Frame> Next() override;
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  int64_t size() const override { return -1; }
  const std::string& error() const override { return error_; }
  bool live() const override { return true; }
  int64_t frames_skipped() const override { return skipped_; }

  struct Counters {
    int64_t delivered = 0, skipped = 0, stalls = 0, disappearances = 0, reopened = 0;
  };
  Counters counters() const;

 private:
  LiveCameraSource(std::unique_ptr<FrameGrabber> grabber, const CameraIntrinsics& intrinsics,
                   const LiveCameraOptions& options)
      : grabber_(std::move(grabber)), intrinsics_(intrinsics), options_(options) {}
  void CaptureLoop();
  bool Stopped() const { return quit_ || (options_.stop != nullptr && *options_.stop); }

  std::unique_ptr<FrameGrabber> grabber_;
  const CameraIntrinsics intrinsics_;
  const LiveCameraOptions options_;
  std::string error_;
  std::atomic<int64_t> skipped_{0};
  std::atomic<bool> quit_{false};

  mutable std::mutex mutex_;
  std::condition_variable arrived_;
  std::deque<Frame> frames_;  // guarded by mutex_
  bool gone_ = false;          // guarded by mutex_: the camera disappeared and is not back yet
  std::string grab_problem_;   // guarded by mutex_: a frame of the wrong size (fatal)
  Counters counters_;          // guarded by mutex_ (skipped: skipped_)

  // Next()'s own state (tracking thread).
  std::chrono::steady_clock::time_point last_frame_;
  bool stall_reported_ = false, gone_reported_ = false;
  std::thread capture_;  // last: started after everything above exists
};

}  // namespace ccm::agent
