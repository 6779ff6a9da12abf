// ccm_ros2_echo: what a ROS 2 tool would see of `ccm_server --ros2` (ros2_test.cpp,
// docs/ros2.md): a plain Fast DDS participant reading the rt/ topics with ROS 2's type names
// and default QoS for --seconds or until SIGTERM / SIGINT. Writes the last path of agent --agent as TUM (--path-out)
// and prints one JSON object: paths received, the last path's poses and frame, /tf messages
// and the child frames seen, the last cloud's width and frame.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <set>

#include "idl/ros2/ros2_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"

namespace rt = ccm::rt;
using std::chrono::milliseconds;

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  rt::SessionOptions options;
  int agent = 1;
  double seconds = 10.0;
  std::string path_out;
  CLI::App app{"ccm_ros2_echo: reads ccm_server --ros2's topics as a ROS 2 tool would (tests)"};
  app.add_option("--domain", options.domain_id, "DDS domain id");
  app.add_option("--qos", options.qos_file, "QoS profiles file");
  app.add_option("--agent", agent, "agent whose path is written")->capture_default_str();
  app.add_option("--seconds", seconds, "how long to listen")->capture_default_str();
  app.add_option("--path-out", path_out, "the last path of the agent (TUM)");
  CLI11_PARSE(app, argc, argv);
  options.participant_name = "ccm_ros2_echo";
  std::string error;
  auto session = rt::DdsSession::Create(options, &error);
  if (!session) return std::cerr << error << "\n", 2;
  auto path = rt::TypedReader<nav_msgs::msg::dds_::Path_PubSubType>::Create(
      *session, rt::Ros2AgentPathTopic(agent), rt::kProfileRos2Reader, {}, &error);
  auto tf = rt::TypedReader<tf2_msgs::msg::dds_::TFMessage_PubSubType>::Create(*session, rt::kTopicRos2Tf,
                                                                              rt::kProfileRos2Reader, {}, &error);
  auto cloud = rt::TypedReader<sensor_msgs::msg::dds_::PointCloud2_PubSubType>::Create(
      *session, rt::kTopicRos2MapPoints, rt::kProfileRos2Reader, {}, &error);
  if (!path || !tf || !cloud) return std::cerr << error << "\n", 2;
  std::optional<nav_msgs::msg::dds_::Path_> last_path;
  std::optional<sensor_msgs::msg::dds_::PointCloud2_> last_cloud;
  int paths = 0, tfs = 0, clouds = 0;
  std::set<std::string> children;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  std::signal(SIGTERM, OnSignal);
  std::signal(SIGINT, OnSignal);
  while (!g_stop && std::chrono::steady_clock::now() < end) {
    if (auto p = path->Pop(milliseconds(50))) last_path = std::move(p), ++paths;
    while (auto m = tf->Pop(milliseconds(0))) {
      ++tfs;
      for (const auto& t : m->transforms()) children.insert(t.header().frame_id() + ">" + t.child_frame_id());
    }
    while (auto c = cloud->Pop(milliseconds(0))) last_cloud = std::move(c), ++clouds;
  }
  nlohmann::json out = {{"paths", paths}, {"tf", tfs}, {"tf_frames", children}, {"clouds", clouds}};
  if (last_path) {
    out["poses"] = last_path->poses().size();
    out["frame_id"] = last_path->header().frame_id();
    if (!path_out.empty()) {
      std::ofstream f(path_out);
      f << std::fixed << std::setprecision(9);
      for (const auto& p : last_path->poses()) {
        const auto& s = p.header().stamp();
        const auto& x = p.pose().position();
        const auto& q = p.pose().orientation();
        f << s.sec() + s.nanosec() * 1e-9 << ' ' << x.x() << ' ' << x.y() << ' ' << x.z() << ' ' << q.x() << ' ' << q.y()
          << ' ' << q.z() << ' ' << q.w() << '\n';
      }
    }
  }
  if (last_cloud) out["cloud"] = {{"width", last_cloud->width()}, {"frame_id", last_cloud->header().frame_id()}};
  std::cout << out.dump() << std::endl;
  return 0;
}
