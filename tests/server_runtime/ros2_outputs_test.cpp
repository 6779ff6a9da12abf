// ccm_server --ros2 (issue 32): the messages built from a back-end with known keyframes and
// points, and the same received over DDS by plain Fast DDS readers using ROS 2's type and
// topic names (what RViz2 / Foxglove subscribe to).
#include "server_runtime/ros2_outputs.h"

#include <gtest/gtest.h>

#include <cstring>

#include "runtime_common/topics.h"
#include "tests/server_runtime/map_view_fixture.h"

namespace ccm::server {
namespace {

using std::chrono::milliseconds;

int64_t Ns(const builtin_interfaces::msg::dds_::Time_& t) { return int64_t{t.sec()} * 1000000000 + t.nanosec(); }

// Agent 1: three keyframes along x in its map (the largest); agent 2: two in a map of its own.
struct Team {
  testing::ViewBackend b;
  std::vector<KeyframeId> one, two;
  Team() {
    for (double x : {0.0, 1.0, 2.0}) one.push_back(b.AddKeyframe(1, x, 5));
    for (double x : {10.0, 13.0}) two.push_back(b.AddKeyframe(2, x, 4));
  }
};

TEST(Ros2Outputs, PathsPosesTfAndCloudFollowTheServerMapsFrameByFrame) {
  Team t;
  const Ros2Frame f = BuildRos2Frame(t.b.backend().Snapshot(), true, 1000);
  ASSERT_EQ(f.agents.size(), 2u);
  const auto& a1 = f.agents[0];
  EXPECT_EQ(a1.id, 1);
  EXPECT_EQ(a1.path.header().frame_id(), "map") << "agent 1 is in the largest map";
  ASSERT_EQ(a1.path.poses().size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const auto& p = a1.path.poses()[i];
    EXPECT_DOUBLE_EQ(p.pose().position().x(), static_cast<double>(i));
    EXPECT_DOUBLE_EQ(p.pose().orientation().w(), 1.0);
    EXPECT_EQ(Ns(p.header().stamp()), static_cast<int64_t>(t.one[i].counter()) * 50000000);
    EXPECT_EQ(p.header().frame_id(), "map");
  }
  EXPECT_DOUBLE_EQ(a1.pose.pose().position().x(), 2.0);
  const auto& a2 = f.agents[1];
  const std::string own = "ccm_map_" + std::to_string(t.b.MapOf(2)->id().counter());
  EXPECT_EQ(a2.path.header().frame_id(), own) << "not fused: its own frame";
  ASSERT_EQ(a2.path.poses().size(), 2u);
  EXPECT_DOUBLE_EQ(a2.pose.pose().position().x(), 13.0);
  ASSERT_EQ(f.tf.transforms().size(), 2u);
  EXPECT_EQ(f.tf.transforms()[0].header().frame_id(), "map");
  EXPECT_EQ(f.tf.transforms()[0].child_frame_id(), "agent_1");
  EXPECT_DOUBLE_EQ(f.tf.transforms()[0].transform().translation().x(), 2.0);
  EXPECT_EQ(f.tf.transforms()[1].header().frame_id(), own);
  EXPECT_EQ(f.tf.transforms()[1].child_frame_id(), "agent_2");
  // The cloud: the largest map's 15 points, x y z float32 little-endian, in "map".
  const auto& c = f.cloud;
  EXPECT_EQ(c.header().frame_id(), "map");
  ASSERT_EQ(c.width(), 15u);
  EXPECT_EQ(c.height(), 1u);
  ASSERT_EQ(c.fields().size(), 3u);
  EXPECT_EQ(c.fields()[2].name(), "z");
  EXPECT_EQ(c.fields()[2].offset(), 8u);
  EXPECT_EQ(c.fields()[2].datatype(), 7);
  EXPECT_EQ(c.point_step(), 12u);
  EXPECT_EQ(c.row_step(), 12u * 15);
  ASSERT_EQ(c.data().size(), 12u * 15);
  const auto points = t.b.MapOf(1)->map().map_points();
  for (size_t i = 0; i < points.size(); ++i) {
    float xyz[3];
    std::memcpy(xyz, c.data().data() + 12 * i, sizeof(xyz));
    EXPECT_NEAR(xyz[0], points[i]->position().x(), 1e-5);
    EXPECT_NEAR(xyz[2], points[i]->position().z(), 1e-5);
  }
  // Decimation keeps at most the bound.
  EXPECT_LE(BuildRos2Frame(t.b.backend().Snapshot(), true, 4).cloud.width(), 4u);
  EXPECT_EQ(BuildRos2Frame(t.b.backend().Snapshot(), false, 4).cloud.width(), 0u);
}

TEST(Ros2Outputs, PlainDdsReadersWithRos2NamesReceiveThem) {
  Team t;
  rt::SessionOptions so;
  so.domain_id = 199;
  so.qos_file = std::string(CCM_SOURCE_DIR) + "/qos_profiles/default.xml";
  std::string error;
  so.participant_name = "ros2_tool";
  auto tool = rt::DdsSession::Create(so, &error);
  ASSERT_TRUE(tool) << error;
  auto path = rt::TypedReader<nav_msgs::msg::dds_::Path_PubSubType>::Create(*tool, "rt/ccm/agent_1/path",
                                                                             rt::kProfileRos2Reader, {}, &error);
  auto tf = rt::TypedReader<tf2_msgs::msg::dds_::TFMessage_PubSubType>::Create(*tool, "rt/tf", rt::kProfileRos2Reader,
                                                                              {}, &error);
  auto cloud = rt::TypedReader<sensor_msgs::msg::dds_::PointCloud2_PubSubType>::Create(
      *tool, "rt/ccm/map_points", rt::kProfileRos2Reader, {}, &error);
  ASSERT_TRUE(path && tf && cloud) << error;
  EXPECT_EQ(std::string(nav_msgs::msg::dds_::Path_PubSubType().getName()), "nav_msgs::msg::dds_::Path_");
  EXPECT_EQ(std::string(tf2_msgs::msg::dds_::TFMessage_PubSubType().getName()), "tf2_msgs::msg::dds_::TFMessage_");
  // As the daemon does: a participant of their own, on the ROS 2 side's domain (199) rather
  // than the team's (here 0, never joined).
  rt::SessionOptions team = so;
  team.domain_id = 0;
  Ros2OutputOptions options;
  options.domain_id = 199;
  auto outputs = Ros2Outputs::CreateWithOwnParticipant(team, options, &error);
  ASSERT_TRUE(outputs) << error;
  EXPECT_EQ(outputs->domain_id(), 199);
  ASSERT_TRUE(outputs->PublishDue(t.b.backend(), 0.0, &error)) << error;  // creates the agents' writers
  ASSERT_TRUE(path->WaitForMatch(1, milliseconds(5000)));
  ASSERT_TRUE(tf->WaitForMatch(1, milliseconds(5000)));
  ASSERT_TRUE(cloud->WaitForMatch(1, milliseconds(5000)));
  EXPECT_TRUE(outputs->PublishDue(t.b.backend(), 0.5, &error));  // not due: nothing
  EXPECT_EQ(outputs->rounds(), 1);
  t.b.AddKeyframe(1, 3.0, 5);
  // A reader's match can come before the writer's (discovery is not symmetric), and ROS 2's
  // QoS is VOLATILE: a round written before the writer saw the reader is not delivered. So
  // rounds go out (each due, each with the cloud) until one arrives, as a ROS 2 tool sees it.
  std::optional<nav_msgs::msg::dds_::Path_> p;
  std::optional<tf2_msgs::msg::dds_::TFMessage_> m;
  std::optional<sensor_msgs::msg::dds_::PointCloud2_> c;
  for (int round = 0; round < 20 && !(p && m && c); ++round) {
    ASSERT_TRUE(outputs->PublishDue(t.b.backend(), 6.0 + 5.0 * round, &error)) << error;
    const auto until = std::chrono::steady_clock::now() + milliseconds(500);
    while (std::chrono::steady_clock::now() < until) {
      if (auto next = path->Pop(milliseconds(20)); next && next->poses().size() == 4) p = next;
      if (auto next = tf->Pop(milliseconds(0)); next && next->transforms()[0].transform().translation().x() == 3.0) {
        m = next;
      }
      if (auto next = cloud->Pop(milliseconds(0))) c = next;
    }
  }
  EXPECT_GE(outputs->rounds(), 2);
  ASSERT_TRUE(p && m && c) << "path " << p.has_value() << " tf " << m.has_value() << " cloud " << c.has_value();
  EXPECT_DOUBLE_EQ(p->poses().back().pose().position().x(), 3.0);
  EXPECT_EQ(p->header().frame_id(), "map");
  ASSERT_EQ(m->transforms().size(), 2u);
  EXPECT_EQ(m->transforms()[0].child_frame_id(), "agent_1");
  EXPECT_GE(c->width(), 15u);
  EXPECT_EQ(c->data().size(), 12u * c->width());
}

TEST(Ros2Outputs, BadOptionsAreRefused) {
  Ros2OutputOptions o;
  o.domain_id = 233;
  EXPECT_NE(o.Validate().find("ros2_domain"), std::string::npos);
  o.domain_id = -1;
  o.period_s = 0.0;
  EXPECT_NE(o.Validate().find("ros2_period_s"), std::string::npos);
  o = Ros2OutputOptions{};
  o.cloud_period_s = 0.5;
  EXPECT_NE(o.Validate().find("ros2_cloud_period_s"), std::string::npos);
  o = Ros2OutputOptions{};
  o.max_cloud_points = 0;
  EXPECT_NE(o.Validate().find("ros2_max_cloud_points"), std::string::npos);
  EXPECT_EQ(Ros2OutputOptions{}.Validate(), "");
}

}  // namespace
}  // namespace ccm::server
