// ccm_agent --ros2-image over DDS in one process: a plain Fast DDS writer with ROS 2's topic and
// type names (as a ROS 2 camera driver's rmw writes them) feeds Ros2CameraSource. Frames arrive
// with their stamps and pixels; the calibration comes from the CameraInfo; a missing camera
// info, a bad encoding, a stall, images from the past and a tracker that falls behind are each
// reported as docs/ros2.md says. The whole agent on a published flight is system_test Ros2Camera.*.
#include "agent_runtime/ros2_camera_source.h"

#include <gtest/gtest.h>

#include <thread>

#include "runtime_common/topics.h"

namespace ccm::agent {
namespace {

using std::chrono::milliseconds;
constexpr int kCameraTestDomain = 195;

// Each test on a topic of its own: ctest runs them as parallel processes on one domain.
std::string TestImageTopic() {
  return std::string("/cam_") + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "/image_raw";
}

struct FakeDriver {
  std::unique_ptr<rt::DdsSession> session;
  std::unique_ptr<rt::TypedWriter<sensor_msgs::msg::dds_::Image_PubSubType>> images;
  std::unique_ptr<rt::TypedWriter<sensor_msgs::msg::dds_::CameraInfo_PubSubType>> infos;

  explicit FakeDriver(const std::string& image_topic = TestImageTopic()) {
    rt::SessionOptions o;
    o.domain_id = kCameraTestDomain;
    o.qos_file = std::string(CCM_SOURCE_DIR) + "/qos_profiles/default.xml";
    o.participant_name = "fake_camera_driver";
    std::string error;
    session = rt::DdsSession::Create(o, &error);
    EXPECT_TRUE(session) << error;
    images = rt::TypedWriter<sensor_msgs::msg::dds_::Image_PubSubType>::Create(
        *session, rt::Ros2DdsTopic(image_topic), rt::kProfileRos2Writer, &error);
    infos = rt::TypedWriter<sensor_msgs::msg::dds_::CameraInfo_PubSubType>::Create(
        *session, rt::Ros2DdsTopic(CameraInfoTopicFor(image_topic)), rt::kProfileRos2Writer, &error);
    EXPECT_TRUE(images && infos) << error;
  }
  void Info(int w = 64, int h = 48) {
    sensor_msgs::msg::dds_::CameraInfo_ info;
    info.width(w);
    info.height(h);
    info.distortion_model("plumb_bob");
    info.d({0.01, 0, 0, 0, 0});
    info.k({50, 0, 32, 0, 51, 24, 0, 0, 1});
    infos->Write(info);
  }
  void Image(int64_t stamp_ns, uint8_t value, const std::string& encoding = "mono8", int w = 64, int h = 48) {
    sensor_msgs::msg::dds_::Image_ img;
    img.header().stamp().sec(static_cast<int32_t>(stamp_ns / 1000000000));
    img.header().stamp().nanosec(static_cast<uint32_t>(stamp_ns % 1000000000));
    img.width(w);
    img.height(h);
    img.encoding(encoding);
    img.step(w);
    img.data().assign(static_cast<size_t>(w) * h, value);
    img.data()[0] = static_cast<uint8_t>(value + 1);  // not uniform: the first pixel tells rows from columns
    images->Write(img);
  }
};

Ros2CameraOptions Options() {
  Ros2CameraOptions o;
  o.image_topic = TestImageTopic();
  o.domain_id = kCameraTestDomain;
  o.qos_file = std::string(CCM_SOURCE_DIR) + "/qos_profiles/default.xml";
  o.info_wait_s = 20.0;
  o.stall_s = 0.3;
  o.end_after_s = 1.0;
  o.queue = 100;
  return o;
}

// Discovery is not symmetric: a BEST_EFFORT sample written before the reader knows the writer
// is dropped, so both sides must have matched before a test writes single images.
void WaitForBothSides(FakeDriver* driver, const Ros2CameraSource& source) {
  ASSERT_TRUE(driver->images->WaitForMatch(1, milliseconds(10000)));
  const auto until = std::chrono::steady_clock::now() + milliseconds(10000);
  while (source.image_publishers() < 1 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(milliseconds(10));
  }
  ASSERT_GE(source.image_publishers(), 1);
}

// The driver publishes its camera info until the source has it (it may start first).
std::unique_ptr<Ros2CameraSource> CreateWithDriver(FakeDriver* driver, const Ros2CameraOptions& options,
                                                   std::string* error) {
  std::atomic<bool> done{false};
  std::thread publisher([&] {
    while (!done) {
      driver->Info();
      std::this_thread::sleep_for(milliseconds(50));
    }
  });
  auto source = Ros2CameraSource::Create(options, error);
  done = true;
  publisher.join();
  if (source) WaitForBothSides(driver, *source);
  return source;
}

TEST(Ros2CameraSource, FramesArriveWithStampsPixelsAndTheCameraInfosCalibration) {
  FakeDriver driver;
  std::string error;
  auto source = CreateWithDriver(&driver, Options(), &error);
  ASSERT_TRUE(source) << error;
  EXPECT_EQ(source->intrinsics().width_px, 64);
  EXPECT_DOUBLE_EQ(source->intrinsics().fy, 51.0);
  EXPECT_EQ(source->intrinsics().distortion.size(), 5u);
  EXPECT_TRUE(source->live());
  const int64_t t0 = 1700000000LL * 1000000000;
  for (int i = 0; i < 5; ++i) driver.Image(t0 + i * 50000000LL, static_cast<uint8_t>(10 * i));
  driver.Image(t0 + 2 * 50000000LL, 99);  // from the past: skipped, counted
  driver.Image(t0 + 5 * 50000000LL, 50);
  for (int i = 0; i < 6; ++i) {
    auto f = source->Next();
    ASSERT_TRUE(f) << "frame " << i << ": " << source->error();
    EXPECT_EQ(f->stamp_ns, t0 + i * 50000000LL);
    EXPECT_EQ(f->image.type(), CV_8UC1);
    EXPECT_EQ(f->image.at<uint8_t>(0, 0), 10 * i + 1);
    EXPECT_EQ(f->image.at<uint8_t>(47, 63), 10 * i);
  }
  EXPECT_FALSE(source->Next());  // silence beyond end_after_s ends the flight ...
  EXPECT_TRUE(source->error().empty()) << source->error();  // ... normally
  const auto c = source->counters();
  EXPECT_EQ(c.delivered, 6);
  EXPECT_EQ(c.out_of_order, 1);
  EXPECT_EQ(c.skipped, 0);
  EXPECT_EQ(c.stalls, 1);
}

TEST(Ros2CameraSource, AStallIsReportedAndTheStreamResumes) {
  FakeDriver driver;
  std::string error;
  Ros2CameraOptions o = Options();
  o.end_after_s = 0;  // wait for ever: the driver comes back
  auto source = CreateWithDriver(&driver, o, &error);
  ASSERT_TRUE(source) << error;
  std::thread late([&] {
    driver.Image(1000, 1);
    std::this_thread::sleep_for(milliseconds(1200));  // 4 stall periods: reported once
    driver.Image(2000, 2);
  });
  ASSERT_TRUE(source->Next());
  auto f = source->Next();
  late.join();
  ASSERT_TRUE(f) << source->error();
  EXPECT_EQ(f->stamp_ns, 2000);
  EXPECT_EQ(source->counters().stalls, 1);
}

TEST(Ros2CameraSource, ATrackerThatFallsBehindGetsTheNewestFrameAndACountOfTheSkipped) {
  FakeDriver driver;
  std::string error;
  Ros2CameraOptions o = Options();
  o.queue = 2;
  auto source = CreateWithDriver(&driver, o, &error);
  ASSERT_TRUE(source) << error;
  for (int i = 1; i <= 10; ++i) driver.Image(i * 1000, static_cast<uint8_t>(i));
  std::this_thread::sleep_for(milliseconds(500));  // all ten are in before the tracker asks
  std::vector<int64_t> got;
  while (auto f = source->Next()) got.push_back(f->stamp_ns);
  const auto c = source->counters();
  // The newest frames; what was pushed out is counted (none lost on one host).
  ASSERT_FALSE(got.empty());
  EXPECT_EQ(got.back(), 10000);
  EXPECT_EQ(c.delivered + c.skipped + c.lost, 10) << c.delivered << " " << c.skipped << " " << c.lost;
  EXPECT_GE(c.skipped, 8 - c.lost);
  EXPECT_EQ(source->frames_skipped(), c.skipped);
}

TEST(Ros2CameraSource, WithoutACameraInfoTheErrorSaysWhatToCheck) {
  FakeDriver driver;
  Ros2CameraOptions o = Options();
  o.info_wait_s = 1.0;
  std::string error;
  EXPECT_FALSE(Ros2CameraSource::Create(o, &error));
  EXPECT_NE(error.find("no sensor_msgs/CameraInfo on DDS topic rt" + CameraInfoTopicFor(TestImageTopic())),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("--calibration"), std::string::npos) << error;
  EXPECT_NE(error.find("--ros2-domain"), std::string::npos) << error;
  // A calibration given instead: no wait, and an image of another size is refused.
  CameraIntrinsics c;
  c.width_px = 32;
  c.height_px = 24;
  c.fx = c.fy = 30;
  c.cx = 16;
  c.cy = 12;
  o.calibration = c;
  auto source = Ros2CameraSource::Create(o, &error);
  ASSERT_TRUE(source) << error;
  WaitForBothSides(&driver, *source);
  driver.Image(1000, 5);
  EXPECT_FALSE(source->Next());
  EXPECT_NE(source->error().find("images are 64x48 but the calibration is for 32x24"), std::string::npos)
      << source->error();
}

TEST(Ros2CameraSource, ABadEncodingEndsTheFlightWithTheReasonAndStopEndsAWait) {
  FakeDriver driver;
  std::string error;
  auto source = CreateWithDriver(&driver, Options(), &error);
  ASSERT_TRUE(source) << error;
  driver.Image(1000, 5, "yuv422");
  EXPECT_FALSE(source->Next());
  EXPECT_NE(source->error().find("rt" + TestImageTopic() + ": image encoding 'yuv422' is not supported"),
            std::string::npos)
      << source->error();
  volatile bool stop = false;
  Ros2CameraOptions o = Options();
  o.end_after_s = 0;
  o.stop = &stop;
  auto waiting = CreateWithDriver(&driver, o, &error);
  ASSERT_TRUE(waiting) << error;
  std::thread signal([&] {
    std::this_thread::sleep_for(milliseconds(300));
    stop = true;
  });
  EXPECT_FALSE(waiting->Next());
  signal.join();
  EXPECT_TRUE(waiting->error().empty());
}

}  // namespace
}  // namespace ccm::agent
