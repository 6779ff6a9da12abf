// ccm_agent --video DEVICE|PIPELINE (issue 29): a live camera without a camera. A scripted
// grabber plays a camera that delivers faster than the tracker takes frames, stalls,
// disappears and comes back, or has the wrong size; a GStreamer pipeline (videotestsrc, what
// OpenCV's GStreamer backend opens for any pipeline string) stands in for a real one.
#include "agent_runtime/live_camera_source.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace ccm::agent {
namespace {

using std::chrono::milliseconds;

CameraIntrinsics TestIntrinsics(int w = 32, int h = 24) {
  CameraIntrinsics c;
  c.width_px = w;
  c.height_px = h;
  c.fx = c.fy = 30;
  c.cx = w / 2.0;
  c.cy = h / 2.0;
  return c;
}

// Frame i has every pixel = i % 256. `script(i)` says what read i does.
struct ScriptedCamera : FrameGrabber {
  enum class Step { kFrame, kFail, kStall };
  std::function<Step(int)> script;
  std::atomic<int> reads{0}, opens{0}, fail_opens{0};
  std::atomic<bool> release{false};
  int period_ms = 2, width = 32;
  bool Open() override {
    ++opens;
    return fail_opens-- <= 0;
  }
  bool Read(cv::Mat* image) override {
    const int i = reads++;
    const Step step = script ? script(i) : Step::kFrame;
    if (step == Step::kStall) {
      while (!release) std::this_thread::sleep_for(milliseconds(5));
      return false;
    }
    if (step == Step::kFail) return false;
    std::this_thread::sleep_for(milliseconds(period_ms));
    *image = cv::Mat(24, width, CV_8UC3, cv::Scalar::all(i % 256));
    return true;
  }
  void Close() override {}
};

LiveCameraOptions CameraOptions() {
  LiveCameraOptions o;
  o.name = "scripted";
  o.stall_s = 0.3;
  o.reopen_s = 0.1;
  o.end_after_s = 1.0;
  return o;
}

TEST(LiveCameraSource, ABusyTrackerGetsTheNewestFrameAndTheSkippedAreCounted) {
  auto grabber = std::make_unique<ScriptedCamera>();
  ScriptedCamera* cam = grabber.get();
  cam->script = [](int i) { return i < 200 ? ScriptedCamera::Step::kFrame : ScriptedCamera::Step::kStall; };
  std::string error;
  auto source = LiveCameraSource::Create(std::move(grabber), TestIntrinsics(), CameraOptions(), &error);
  ASSERT_TRUE(source) << error;
  std::vector<int> values;
  while (auto f = source->Next()) {
    ASSERT_EQ(f->image.type(), CV_8UC1);
    values.push_back(f->image.at<uint8_t>(0, 0));
    std::this_thread::sleep_for(milliseconds(10));  // tracking: 5 camera frames per frame
  }
  EXPECT_TRUE(source->error().empty()) << source->error();
  const auto c = source->counters();
  EXPECT_EQ(c.delivered + c.skipped, 200) << c.delivered << " + " << c.skipped;
  EXPECT_GE(c.skipped, 100);
  EXPECT_EQ(values.back(), 199);  // the last frame is never skipped
  for (size_t i = 1; i < values.size(); ++i) EXPECT_LT(values[i - 1], values[i]);
  EXPECT_EQ(c.stalls, 1);
  cam->release = true;  // the capture thread's read returns: the source can join it
}

TEST(LiveCameraSource, ACameraThatDisappearsIsReopenedAndTheFlightGoesOn) {
  auto grabber = std::make_unique<ScriptedCamera>();
  ScriptedCamera* cam = grabber.get();
  cam->period_ms = 20;  // slower than the tracker: nothing skipped
  cam->script = [cam](int i) {
    if (i == 5) {
      cam->fail_opens = 2;  // unplugged: the next two opens fail
      return ScriptedCamera::Step::kFail;
    }
    return i <= 10 ? ScriptedCamera::Step::kFrame : ScriptedCamera::Step::kStall;
  };
  std::string error;
  auto source = LiveCameraSource::Create(std::move(grabber), TestIntrinsics(), CameraOptions(), &error);
  ASSERT_TRUE(source) << error;
  int frames = 0;
  while (source->Next()) ++frames;
  EXPECT_TRUE(source->error().empty()) << source->error();
  const auto c = source->counters();
  EXPECT_EQ(frames, 10);
  EXPECT_EQ(c.skipped, 0);
  EXPECT_EQ(c.disappearances, 1);
  EXPECT_EQ(c.reopened, 1);
  EXPECT_EQ(cam->opens.load(), 4);  // the first, two that failed, the one that worked
  cam->release = true;
}

TEST(LiveCameraSource, AWrongSizeOrAnUnopenableCameraIsReportedAndStopEndsAWait) {
  auto wrong = std::make_unique<ScriptedCamera>();
  wrong->width = 40;
  std::string error;
  auto source = LiveCameraSource::Create(std::move(wrong), TestIntrinsics(), CameraOptions(), &error);
  ASSERT_TRUE(source) << error;
  EXPECT_FALSE(source->Next());
  EXPECT_NE(source->error().find("scripted: delivers 40x24 but the calibration is for 32x24"), std::string::npos)
      << source->error();
  auto dead = std::make_unique<ScriptedCamera>();
  dead->fail_opens = 1;
  EXPECT_FALSE(LiveCameraSource::Create(std::move(dead), TestIntrinsics(), CameraOptions(), &error));
  EXPECT_NE(error.find("cannot open the camera"), std::string::npos) << error;
  // A stalled camera and no end-after: SIGINT (the stop flag) ends the wait.
  auto stalled = std::make_unique<ScriptedCamera>();
  ScriptedCamera* cam = stalled.get();
  cam->script = [](int) { return ScriptedCamera::Step::kStall; };
  volatile bool stop = false;
  LiveCameraOptions o = CameraOptions();
  o.end_after_s = 0;
  o.stop = &stop;
  auto waiting = LiveCameraSource::Create(std::move(stalled), TestIntrinsics(), o, &error);
  ASSERT_TRUE(waiting) << error;
  std::thread signal([&] {
    std::this_thread::sleep_for(milliseconds(400));
    stop = true;
    cam->release = true;
  });
  EXPECT_FALSE(waiting->Next());
  signal.join();
  EXPECT_TRUE(waiting->error().empty());
  EXPECT_EQ(waiting->counters().stalls, 1);
}

// OpenCV's GStreamer backend on a pipeline string, as `--video "... ! appsink"` opens it:
// 20 frames, then the pipeline ends (the camera disappears) and is opened again.
TEST(LiveCameraSource, AGStreamerPipelineDeliversFramesAndIsReopenedAtItsEnd) {
  const std::string pipeline =
      "videotestsrc num-buffers=20 pattern=ball ! video/x-raw,width=64,height=48 ! videoconvert ! "
      "video/x-raw,format=BGR ! appsink";
  ASSERT_TRUE(IsGStreamerPipeline(pipeline));
  ASSERT_FALSE(IsGStreamerPipeline("/dev/video0"));
  LiveCameraOptions o = CameraOptions();
  o.name = "gst";
  o.queue = 100;
  std::string error;
  auto source = LiveCameraSource::Create(MakeOpenCvGrabber(pipeline), TestIntrinsics(64, 48), o, &error);
  ASSERT_TRUE(source) << error << " (needs gstreamer1.0-plugins-base: deploy/install-deps.sh)";
  int frames = 0;
  while (frames < 30) {
    auto f = source->Next();
    ASSERT_TRUE(f) << source->error();
    EXPECT_EQ(f->image.cols, 64);
    EXPECT_EQ(f->image.type(), CV_8UC1);
    ++frames;
  }
  const auto c = source->counters();
  EXPECT_GE(c.disappearances, 1);
  EXPECT_GE(c.reopened, 1);
}

}  // namespace
}  // namespace ccm::agent
