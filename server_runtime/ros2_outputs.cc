#include "server_runtime/ros2_outputs.h"

#include <cstring>
#include <set>
#include <shared_mutex>

#include "runtime_common/topics.h"

namespace ccm::server {
namespace {

using geometry_msgs::msg::dds_::PoseStamped_;

builtin_interfaces::msg::dds_::Time_ RosTime(int64_t stamp_ns) {
  builtin_interfaces::msg::dds_::Time_ t;
  const int64_t sec = stamp_ns >= 0 ? stamp_ns / 1000000000 : (stamp_ns - 999999999) / 1000000000;
  t.sec(static_cast<int32_t>(sec));
  t.nanosec(static_cast<uint32_t>(stamp_ns - sec * 1000000000));
  return t;
}

std_msgs::msg::dds_::Header_ Header(int64_t stamp_ns, const std::string& frame) {
  std_msgs::msg::dds_::Header_ h;
  h.stamp(RosTime(stamp_ns));
  h.frame_id(frame);
  return h;
}

PoseStamped_ RosPose(const ServerKeyframePose& k, const std::string& frame) {
  PoseStamped_ p;
  p.header(Header(k.stamp_ns, frame));
  const Eigen::Vector3d& t = k.world_from_cam.translation();
  const Eigen::Quaterniond q = k.world_from_cam.rotation().normalized();
  p.pose().position().x(t.x());
  p.pose().position().y(t.y());
  p.pose().position().z(t.z());
  p.pose().orientation().x(q.x());
  p.pose().orientation().y(q.y());
  p.pose().orientation().z(q.z());
  p.pose().orientation().w(q.w());
  return p;
}

geometry_msgs::msg::dds_::TransformStamped_ RosTransform(const PoseStamped_& pose, const std::string& child) {
  geometry_msgs::msg::dds_::TransformStamped_ t;
  t.header(pose.header());
  t.child_frame_id(child);
  const auto& p = pose.pose();
  t.transform().translation().x(p.position().x());
  t.transform().translation().y(p.position().y());
  t.transform().translation().z(p.position().z());
  t.transform().rotation(p.orientation());
  return t;
}

MapId LargestMap(const MapStackSnapshot& stack) {
  MapId largest;
  size_t most = 0;
  for (const MapSummary& m : stack.Summaries()) {
    if (!largest.valid() || m.keyframes > most || (m.keyframes == most && m.id.packed() < largest.packed())) {
      largest = m.id;
      most = m.keyframes;
    }
  }
  return largest;
}

sensor_msgs::msg::dds_::PointCloud2_ Cloud(const ServerMap& map, size_t max_points, int64_t stamp_ns) {
  sensor_msgs::msg::dds_::PointCloud2_ c;
  c.header(Header(stamp_ns, "map"));
  std::vector<Eigen::Vector3d> points;
  {
    std::shared_lock<WriterPreferringMutex> lock(map.structure_mutex());
    const auto all = map.map().map_points();
    const size_t stride = max_points > 0 && all.size() > max_points ? (all.size() + max_points - 1) / max_points : 1;
    for (size_t i = 0; i < all.size(); i += stride) points.push_back(all[i]->position());
  }
  for (const char* name : {"x", "y", "z"}) {
    sensor_msgs::msg::dds_::PointField_ f;
    f.name(name);
    f.offset(static_cast<uint32_t>(4 * c.fields().size()));
    f.datatype(7);  // FLOAT32
    f.count(1);
    c.fields().push_back(f);
  }
  c.height(1);
  c.width(static_cast<uint32_t>(points.size()));
  c.is_bigendian(false);  // x86-64 and arm64 ground stations are little-endian
  c.point_step(12);
  c.row_step(static_cast<uint32_t>(12 * points.size()));
  c.is_dense(true);
  c.data().resize(12 * points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const float xyz[3] = {static_cast<float>(points[i].x()), static_cast<float>(points[i].y()),
                          static_cast<float>(points[i].z())};
    std::memcpy(c.data().data() + 12 * i, xyz, sizeof(xyz));
  }
  return c;
}

}  // namespace

std::string Ros2OutputOptions::Validate() const {
  if (!(period_s >= 0.05)) return "ros2_period_s must be >= 0.05";
  if (!(cloud_period_s >= period_s)) return "ros2_cloud_period_s must be >= ros2_period_s";
  if (max_cloud_points < 1 || max_cloud_points > 1000000) return "ros2_max_cloud_points must be in 1..1000000";
  if (domain_id < -1 || domain_id > 232) return "ros2_domain must be in 0..232 (-1: the server's domain)";
  return "";
}

std::string Ros2FrameId(MapId map, MapId largest) {
  if (map == largest) return "map";
  // Server maps are numbered by the stack (agent part 0); keep the agent part if there is one.
  return "ccm_map_" + (map.agent() != 0 ? std::to_string(map.agent()) + "_" : std::string()) +
         std::to_string(map.counter());
}

Ros2Frame BuildRos2Frame(const MapStackSnapshot& stack, bool with_cloud, size_t max_cloud_points) {
  Ros2Frame frame;
  const MapId largest = LargestMap(stack);
  std::set<AgentId> agents;
  for (const AgentHandler& h : stack.handlers) agents.insert(h.agent);
  int64_t newest_ns = 0;
  for (const AgentId id : agents) {
    const std::vector<ServerKeyframePose> trajectory = stack.AgentTrajectory(id);
    if (trajectory.empty()) continue;
    const MapId current = trajectory.back().map;  // where its newest keyframe is
    const std::string map_frame = Ros2FrameId(current, largest);
    Ros2Frame::Agent a;
    a.id = id;
    a.path.header(Header(trajectory.back().stamp_ns, map_frame));
    for (const ServerKeyframePose& k : trajectory) {
      if (k.map == current) a.path.poses().push_back(RosPose(k, map_frame));
    }
    a.pose = RosPose(trajectory.back(), map_frame);
    frame.tf.transforms().push_back(RosTransform(a.pose, "agent_" + std::to_string(id)));
    newest_ns = std::max(newest_ns, trajectory.back().stamp_ns);
    frame.agents.push_back(std::move(a));
  }
  const auto map = largest.valid() ? stack.Map(largest) : nullptr;
  if (with_cloud && map) frame.cloud = Cloud(*map, max_cloud_points, newest_ns);
  return frame;
}

std::unique_ptr<Ros2Outputs> Ros2Outputs::Create(rt::DdsSession& session, const Ros2OutputOptions& options,
                                                 std::string* error) {
  if (const std::string problem = options.Validate(); !problem.empty()) {
    *error = problem;
    return nullptr;
  }
  std::unique_ptr<Ros2Outputs> r(new Ros2Outputs(session, options));
  r->tf_ = rt::TypedWriter<tf2_msgs::msg::dds_::TFMessage_PubSubType>::Create(session, rt::kTopicRos2Tf,
                                                                              rt::kProfileRos2Writer, error);
  if (!r->tf_) return nullptr;
  r->cloud_ = rt::TypedWriter<sensor_msgs::msg::dds_::PointCloud2_PubSubType>::Create(
      session, rt::kTopicRos2MapPoints, rt::kProfileRos2Writer, error);
  if (!r->cloud_) return nullptr;
  return r;
}

std::unique_ptr<Ros2Outputs> Ros2Outputs::CreateWithOwnParticipant(const rt::SessionOptions& team,
                                                                   const Ros2OutputOptions& options,
                                                                   std::string* error) {
  if (const std::string problem = options.Validate(); !problem.empty()) {
    *error = problem;
    return nullptr;
  }
  rt::SessionOptions ros_side;
  ros_side.domain_id = options.domain_id >= 0 ? options.domain_id : team.domain_id;
  ros_side.qos_file = team.qos_file;
  ros_side.participant_profile = rt::kProfileRos2Participant;
  ros_side.participant_name = "ccm_server_ros2";
  auto session = rt::DdsSession::Create(ros_side, error);
  if (!session) {
    *error = "ROS 2 outputs: " + *error;
    return nullptr;
  }
  auto outputs = Create(*session, options, error);
  if (outputs) outputs->own_session_ = std::move(session);
  return outputs;
}

bool Ros2Outputs::PublishDue(const ServerBackend& backend, double now_s, std::string* error) {
  if (now_s < next_s_) return true;
  next_s_ = now_s + options_.period_s;
  const bool with_cloud = now_s >= next_cloud_s_;
  if (with_cloud) next_cloud_s_ = now_s + options_.cloud_period_s;
  const Ros2Frame frame = BuildRos2Frame(backend.Snapshot(), with_cloud, options_.max_cloud_points);
  for (const Ros2Frame::Agent& a : frame.agents) {
    AgentWriters& w = agents_[a.id];
    if (!w.path) {
      w.path = rt::TypedWriter<nav_msgs::msg::dds_::Path_PubSubType>::Create(
          session_, rt::Ros2AgentPathTopic(a.id), rt::kProfileRos2Writer, error);
      w.pose = rt::TypedWriter<geometry_msgs::msg::dds_::PoseStamped_PubSubType>::Create(
          session_, rt::Ros2AgentPoseTopic(a.id), rt::kProfileRos2Writer, error);
      if (!w.path || !w.pose) {
        agents_.erase(a.id);
        return false;
      }
    }
    w.path->Write(a.path);
    w.pose->Write(a.pose);
  }
  if (!frame.tf.transforms().empty()) tf_->Write(frame.tf);
  if (with_cloud && frame.cloud.width() > 0) cloud_->Write(frame.cloud);
  ++rounds_;
  return true;
}

}  // namespace ccm::server
