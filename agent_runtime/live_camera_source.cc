#include "agent_runtime/live_camera_source.h"

#include <spdlog/spdlog.h>

#include <opencv2/videoio.hpp>

#include "slam_core/common/stopwatch.h"
#include "slam_core/io/video_source.h"

namespace ccm::agent {
namespace {

using Clock = std::chrono::steady_clock;
// How often a waiting Next() looks at *stop and the clock.
constexpr std::chrono::milliseconds kCameraPoll(100);

int64_t WallClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

class OpenCvGrabber : public FrameGrabber {
 public:
  explicit OpenCvGrabber(std::string input) : input_(std::move(input)) {}
  bool Open() override {
    const bool index = IsCameraIndex(input_);
    if (IsGStreamerPipeline(input_)) return capture_.open(input_, cv::CAP_GSTREAMER) && capture_.isOpened();
    return (index ? capture_.open(std::stoi(input_)) : capture_.open(input_)) && capture_.isOpened();
  }
  bool Read(cv::Mat* image) override { return capture_.read(*image) && !image->empty(); }
  void Close() override { capture_.release(); }

 private:
  std::string input_;
  cv::VideoCapture capture_;
};

}  // namespace

bool IsGStreamerPipeline(const std::string& input) { return input.find('!') != std::string::npos; }

std::unique_ptr<FrameGrabber> MakeOpenCvGrabber(const std::string& device_or_pipeline) {
  return std::make_unique<OpenCvGrabber>(device_or_pipeline);
}

std::unique_ptr<LiveCameraSource> LiveCameraSource::Create(std::unique_ptr<FrameGrabber> grabber,
                                                           const CameraIntrinsics& intrinsics,
                                                           const LiveCameraOptions& options, std::string* error) {
  if (options.queue < 1 || !(options.stall_s > 0) || !(options.reopen_s > 0) || !(options.end_after_s >= 0)) {
    *error = "live camera options: queue >= 1, stall and reopen periods > 0, end-after >= 0";
    return nullptr;
  }
  if (!grabber->Open()) {
    *error = options.name + ": cannot open the camera" +
             (IsGStreamerPipeline(options.name) ? std::string(" pipeline (does it end in appsink? gst-launch-1.0 "
                                                              "shows what GStreamer says)")
                                                : std::string(" (no such device, or busy?)"));
    return nullptr;
  }
  std::unique_ptr<LiveCameraSource> s(new LiveCameraSource(std::move(grabber), intrinsics, options));
  s->last_frame_ = Clock::now();
  s->capture_ = std::thread([src = s.get()] { src->CaptureLoop(); });
  return s;
}

LiveCameraSource::~LiveCameraSource() {
  quit_ = true;
  // A read blocked on a silent camera returns at the driver's timeout (V4L2: 10 s).
  if (capture_.joinable()) capture_.join();
  grabber_->Close();
}

// The capture thread: grab as fast as the camera delivers, keep the newest.
void LiveCameraSource::CaptureLoop() {
  bool open = true;
  while (!Stopped()) {
    if (!open) {
      const auto retry = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                            std::chrono::duration<double>(options_.reopen_s));
      while (!Stopped() && Clock::now() < retry) std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (Stopped() || !grabber_->Open()) continue;
      open = true;
      std::lock_guard<std::mutex> lock(mutex_);
      gone_ = false;
      ++counters_.reopened;
      arrived_.notify_all();
      continue;
    }
    cv::Mat image;
    if (!grabber_->Read(&image)) {
      grabber_->Close();
      open = false;
      std::lock_guard<std::mutex> lock(mutex_);
      gone_ = true;
      ++counters_.disappearances;
      arrived_.notify_all();
      continue;
    }
    Frame f;
    f.stamp_ns = WallClockNs();
    f.image = GrayFromCapture(image);
    std::lock_guard<std::mutex> lock(mutex_);
    if (f.image.cols != intrinsics_.width_px || f.image.rows != intrinsics_.height_px || f.image.depth() != CV_8U) {
      grab_problem_ = options_.name + ": delivers " + std::to_string(f.image.cols) + "x" + std::to_string(f.image.rows) +
                      (f.image.depth() != CV_8U ? " (not 8-bit)" : "") + " but the calibration is for " +
                      std::to_string(intrinsics_.width_px) + "x" + std::to_string(intrinsics_.height_px);
      arrived_.notify_all();
      return;
    }
    frames_.push_back(std::move(f));
    if (frames_.size() > options_.queue) {
      frames_.pop_front();
      ++skipped_;
    }
    arrived_.notify_all();
  }
}

std::optional<Frame> LiveCameraSource::Next() {
  while (!Stopped()) {
    std::unique_lock<std::mutex> lock(mutex_);
    arrived_.wait_for(lock, kCameraPoll, [&] { return !frames_.empty() || !grab_problem_.empty() || gone_ != gone_reported_; });
    if (!grab_problem_.empty()) {
      error_ = grab_problem_;
      return std::nullopt;
    }
    if (gone_ != gone_reported_) {
      gone_reported_ = gone_;
      if (gone_) {
        spdlog::warn("camera {} disappeared (no frame could be read) after {} frames; reopening every {:.1f} s, the VO "
                     "keeps its map", options_.name, counters_.delivered, options_.reopen_s);
      } else {
        spdlog::info("camera {} is back after {:.1f} s", options_.name, SecondsSince(last_frame_));
      }
    }
    if (!frames_.empty()) {
      Frame f = std::move(frames_.front());
      frames_.pop_front();
      f.source_name = options_.name + ":" + std::to_string(counters_.delivered++);
      lock.unlock();
      if (stall_reported_) spdlog::info("camera {}: frames again after {:.1f} s", options_.name, SecondsSince(last_frame_));
      stall_reported_ = false;
      last_frame_ = Clock::now();
      return f;
    }
    const double silent_s = SecondsSince(last_frame_);
    if (silent_s >= options_.stall_s && !stall_reported_ && !gone_reported_) {
      stall_reported_ = true;
      ++counters_.stalls;
      spdlog::warn("camera {}: no frame for {:.1f} s after {} frames (stalled?); waiting, the VO keeps its map",
                   options_.name, silent_s, counters_.delivered);
    }
    lock.unlock();
    if (options_.end_after_s > 0 && silent_s >= options_.end_after_s) {
      spdlog::info("camera {}: no frame for {:.1f} s: the flight ends", options_.name, silent_s);
      return std::nullopt;
    }
  }
  return std::nullopt;
}

LiveCameraSource::Counters LiveCameraSource::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Counters c = counters_;
  c.skipped = skipped_;
  return c;
}

}  // namespace ccm::agent
