// ccm_ros2_camera: a ROS 2 camera driver as seen on the wire, without ROS (tests of
// ccm_agent --ros2-image, docs/ros2.md): renders a simulated agent's flight and publishes each
// frame as sensor_msgs/Image with a sensor_msgs/CameraInfo beside it (as camera drivers do),
// on rt/ topics with ROS 2's type names, at --rate Hz. Waits for a subscriber first. Faults on
// request: another encoding (also unsupported ones), no camera info, a stall of --stall-s
// seconds after --stall-at frames, or the publisher leaving after --frames. Writes the ground
// truth of the published frames (TUM) and prints one JSON object.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstring>
#include <iostream>
#include <thread>

#include "idl/ros2/ros2_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"
#include "slam_core/io/trajectory_io.h"
#include "tests/sim/scenario.h"
#include "tests/sim/sim_frame_source.h"

namespace rt = ccm::rt;
using Clock = std::chrono::steady_clock;

namespace {

std_msgs::msg::dds_::Header_ Header(int64_t stamp_ns, const std::string& frame) {
  std_msgs::msg::dds_::Header_ h;
  h.stamp().sec(static_cast<int32_t>(stamp_ns / 1000000000));
  h.stamp().nanosec(static_cast<uint32_t>(stamp_ns % 1000000000));
  h.frame_id(frame);
  return h;
}

sensor_msgs::msg::dds_::CameraInfo_ Info(const ccm::CameraIntrinsics& c, int64_t stamp_ns) {
  sensor_msgs::msg::dds_::CameraInfo_ info;
  info.header(Header(stamp_ns, "camera"));
  info.width(static_cast<uint32_t>(c.width_px));
  info.height(static_cast<uint32_t>(c.height_px));
  if (c.type == ccm::CameraType::kFisheyeEquidistant) {
    info.distortion_model("equidistant");
    info.d(c.distortion);
  } else {
    info.distortion_model("plumb_bob");
    std::vector<double> d = c.distortion;
    d.resize(5, 0.0);  // k1 k2 t1 t2 k3
    info.d(d);
  }
  info.k({c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1});
  info.r({1, 0, 0, 0, 1, 0, 0, 0, 1});
  info.p({c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0});
  return info;
}

// The gray frame in `encoding` (mono8 / bgr8 / rgb8 / bgra8 exactly; anything else is sent
// as 2 bytes per pixel under that name, for the refusal tests). Rows padded by `pad` bytes.
sensor_msgs::msg::dds_::Image_ Image(const cv::Mat& gray, const std::string& encoding, int pad, int64_t stamp_ns) {
  cv::Mat m;
  if (encoding == "bgr8" || encoding == "rgb8") {
    cv::cvtColor(gray, m, cv::COLOR_GRAY2BGR);  // equal channels: either order
  } else if (encoding == "bgra8") {
    cv::cvtColor(gray, m, cv::COLOR_GRAY2BGRA);
  } else if (encoding == "mono8") {
    m = gray;
  } else {
    cv::Mat planes[] = {gray, gray};
    cv::merge(planes, 2, m);
  }
  sensor_msgs::msg::dds_::Image_ img;
  img.header(Header(stamp_ns, "camera"));
  img.width(static_cast<uint32_t>(m.cols));
  img.height(static_cast<uint32_t>(m.rows));
  img.encoding(encoding);
  img.is_bigendian(0);
  const size_t row = m.cols * m.elemSize();
  img.step(static_cast<uint32_t>(row + pad));
  img.data().assign(img.step() * m.rows, 0);
  for (int r = 0; r < m.rows; ++r) std::memcpy(img.data().data() + r * img.step(), m.ptr(r), row);
  return img;
}

}  // namespace

int main(int argc, char** argv) {
  rt::SessionOptions options;
  std::string scenario_name = "hall3", encoding = "mono8", image_topic = "/camera/image_raw", info_topic,
              ground_truth_out;
  int agent = 0, frames = 300, pad = 0, stall_at = -1;
  double rate_hz = 20.0, stall_s = 0.0, wait_s = 30.0;
  bool no_info = false;
  CLI::App app{"ccm_ros2_camera: publishes a simulated flight as a ROS 2 camera driver would (tests)"};
  app.add_option("--domain", options.domain_id, "DDS domain id");
  app.add_option("--qos", options.qos_file, "QoS profiles file");
  app.add_option("--sim", scenario_name, "scenario")->capture_default_str();
  app.add_option("--sim-agent", agent, "agent index")->capture_default_str();
  app.add_option("--frames", frames, "frames to publish")->capture_default_str();
  app.add_option("--rate", rate_hz, "frames per second")->capture_default_str();
  app.add_option("--encoding", encoding, "mono8, bgr8, rgb8, bgra8 (others: refused by the agent)")->capture_default_str();
  app.add_option("--row-padding", pad, "bytes after each row (step > width)");
  app.add_option("--image-topic", image_topic, "ROS 2 topic of the images")->capture_default_str();
  app.add_option("--info-topic", info_topic, "ROS 2 topic of the camera info (default: beside the images)");
  app.add_flag("--no-camera-info", no_info, "publish no camera info");
  app.add_option("--stall-at", stall_at, "stop publishing after this many frames ...");
  app.add_option("--stall-s", stall_s, "... for this many seconds, then go on");
  app.add_option("--wait", wait_s, "wait this long for a subscriber")->capture_default_str();
  app.add_option("--ground-truth", ground_truth_out, "ground truth of the published frames (TUM)");
  CLI11_PARSE(app, argc, argv);
  if (info_topic.empty()) info_topic = image_topic.substr(0, image_topic.rfind('/') + 1) + "camera_info";
  std::string error;
  const auto scenario = ccm::sim::LoadScenario(scenario_name, &error);
  if (!scenario) return std::cerr << error << "\n", 2;
  std::shared_ptr<const ccm::sim::Simulation> sim(ccm::sim::Simulation::Create(*scenario, &error));
  if (!sim) return std::cerr << error << "\n", 2;
  ccm::sim::SimFrameSource source(sim, agent, 0, 1, frames);
  options.participant_name = "ccm_ros2_camera";
  auto session = rt::DdsSession::Create(options, &error);
  if (!session) return std::cerr << error << "\n", 2;
  auto images = rt::TypedWriter<sensor_msgs::msg::dds_::Image_PubSubType>::Create(
      *session, rt::Ros2DdsTopic(image_topic), rt::kProfileRos2Writer, &error);
  auto infos = rt::TypedWriter<sensor_msgs::msg::dds_::CameraInfo_PubSubType>::Create(
      *session, rt::Ros2DdsTopic(info_topic), rt::kProfileRos2Writer, &error);
  if (!images || !infos) return std::cerr << error << "\n", 2;
  if (!images->WaitForMatch(1, std::chrono::milliseconds(static_cast<int>(wait_s * 1000)))) {
    return std::cerr << "no subscriber to " << image_topic << " within " << wait_s << " s\n", 1;
  }
  // The reader may learn of this writer a little after the writer learnt of it (discovery is
  // not symmetric), and BEST_EFFORT samples sent before that are dropped: a moment for both.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ccm::Trajectory truth;
  int published = 0, failed = 0;
  const auto start = Clock::now();
  double paused_s = 0.0;
  while (auto frame = source.Next()) {
    if (published == stall_at && stall_s > 0) {
      std::this_thread::sleep_for(std::chrono::duration<double>(stall_s));
      paused_s += stall_s;
    }
    std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                              std::chrono::duration<double>(published / rate_hz + paused_s)));
    if (!no_info && !infos->Write(Info(source.intrinsics(), frame->stamp_ns))) ++failed;
    if (!images->Write(Image(frame->image, encoding, pad, frame->stamp_ns))) ++failed;
    if (frame->world_from_cam_gt) truth.push_back({frame->stamp_ns, *frame->world_from_cam_gt});
    ++published;
  }
  // Let the last samples leave before the participant goes.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  if (!ground_truth_out.empty()) {
    if (const auto s = ccm::WriteTumTrajectory(ground_truth_out, truth); !s.ok()) return std::cerr << s.message() << "\n", 1;
  }
  std::cout << nlohmann::json{{"published", published}, {"write_failures", failed}}.dump() << std::endl;
  return failed == 0 ? 0 : 1;
}
