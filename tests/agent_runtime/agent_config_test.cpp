#include "agent_runtime/agent_config.h"

#include <gtest/gtest.h>

#include <fstream>

namespace ccm::agent {
namespace {

std::string Write(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(AgentConfig, NewDataPerCycleStaysWithinTheWritersCap) {
  // wifi.xml: 50000 B per 50 ms = 1 MB/s; at 4 Hz a cycle may offer 0.75 MB/s / 4.
  EXPECT_EQ(NewDataBytesPerCycle(600000, 1.0e6, 4.0), 187500);
  EXPECT_LE(NewDataBytesPerCycle(600000, 1.0e6, 4.0) * 4.0, 1.0e6) << "never more than the cap per second";
  EXPECT_EQ(NewDataBytesPerCycle(100000, 1.0e6, 4.0), 100000) << "a smaller configured budget stays";
  EXPECT_EQ(NewDataBytesPerCycle(600000, 0.0, 4.0), 600000) << "uncapped writer";
  EXPECT_EQ(NewDataBytesPerCycle(600000, 2000.0, 4.0), 1000) << "at least 1000 bytes";
}

TEST(AgentConfig, LoadsValidFile) {
  AgentConfig c;
  std::string error;
  ASSERT_TRUE(LoadAgentConfig(Write("a.yaml", "agent_id: 7\nmax_keyframes: 10\nbuffer_keyframes: 10\nvocabulary: none\n"), &c,
                              &error))
      << error;
  EXPECT_EQ(c.agent_id, 7);
  EXPECT_EQ(c.vocabulary, "none");
  EXPECT_EQ(c.max_keyframes, 10);
  EXPECT_DOUBLE_EQ(c.publish_rate_hz, 4.0);
  EXPECT_TRUE(c.map_sharing);
  EXPECT_EQ(c.opencv_threads, 1) << "OpenCV's pool cost more CPU than it saved (docs/deployment.md)";
  EXPECT_DOUBLE_EQ(c.anchor_duplicates.distance_ratio, 0.10) << "near-duplicates leave as anchors by default";
  ASSERT_TRUE(LoadAgentConfig(Write("a2.yaml", "anchor_duplicate_distance_ratio: 0\n"), &c, &error)) << error;
  EXPECT_FALSE(c.anchor_duplicates.enabled());
}

TEST(AgentConfig, RejectsUnknownKeyWrongTypeAndBadValue) {
  AgentConfig c;
  std::string error;
  EXPECT_FALSE(LoadAgentConfig(Write("b.yaml", "agent_idd: 7\n"), &c, &error));
  EXPECT_NE(error.find("agent_idd"), std::string::npos) << error;
  EXPECT_FALSE(LoadAgentConfig(Write("c.yaml", "agent_id: seven\n"), &c, &error));
  EXPECT_NE(error.find("agent_id"), std::string::npos) << error;
  EXPECT_FALSE(LoadAgentConfig(Write("d.yaml", "agent_id: 0\n"), &c, &error));
  EXPECT_NE(error.find("1..65535"), std::string::npos) << error;
  AgentConfig fresh;
  EXPECT_FALSE(LoadAgentConfig(Write("d2.yaml", "anchor_duplicate_distance_ratio: 1.5\n"), &fresh, &error));
  EXPECT_NE(error.find("anchor_duplicate_distance_ratio must be in [0, 1)"), std::string::npos) << error;
  EXPECT_FALSE(LoadAgentConfig("/nonexistent.yaml", &c, &error));
  EXPECT_NE(error.find("does not exist"), std::string::npos) << error;
}

TEST(AgentConfig, VoSectionSetsOptionsAndIsStrict) {
  AgentConfig c;
  std::string error;
  ASSERT_TRUE(LoadAgentConfig(Write("e.yaml", "vo:\n  init_min_homography_ratio: 0.45\n  features: 1500\n"), &c, &error))
      << error;
  EXPECT_DOUBLE_EQ(c.vo.init_min_homography_ratio, 0.45);
  EXPECT_EQ(c.vo.orb.num_features, 1500);
  EXPECT_FALSE(LoadAgentConfig(Write("f.yaml", "vo:\n  featurs: 1500\n"), &c, &error));
  EXPECT_NE(error.find("featurs"), std::string::npos) << error;
  AgentConfig d;
  EXPECT_FALSE(LoadAgentConfig(Write("g.yaml", "vo:\n  init_min_homography_ratio: 1.5\n"), &d, &error));
  EXPECT_NE(error.find("init_min_homography_ratio"), std::string::npos) << error;
  EXPECT_FALSE(LoadAgentConfig(Write("h.yaml", "vo: 3\n"), &d, &error));
  EXPECT_NE(error.find("vo"), std::string::npos) << error;
  // The triangulation keys (docs/vo.md, "Where the VO's scale goes wrong").
  AgentConfig t;
  ASSERT_TRUE(LoadAgentConfig(Write("t.yaml", "vo:\n  triangulation_parallax_sigmas: 10\n  min_triangulation_parallax_deg: 1.5\n"
                                              "  min_baseline_depth_ratio: 0.02\n"
                                              "  local_ba_max_fixed: 20\n  init_min_rotation_residual_deg: 1\n"
                                              "  init_min_motion_cost_gap: 0\n  init_max_ambiguous_attempts: 5\n"),
                              &t, &error))
      << error;
  EXPECT_DOUBLE_EQ(t.vo.init_min_rotation_residual_deg, 1.0);
  EXPECT_DOUBLE_EQ(t.vo.init_min_motion_cost_gap, 0.0);
  EXPECT_EQ(t.vo.init_max_ambiguous_attempts, 5);
  EXPECT_GT(VoOptions{}.init_min_motion_cost_gap, 0.0) << "the rival-motion check is on by default";
  EXPECT_DOUBLE_EQ(t.vo.triangulation_parallax_sigmas, 10.0);
  EXPECT_DOUBLE_EQ(t.vo.min_triangulation_parallax_deg, 1.5);
  EXPECT_DOUBLE_EQ(t.vo.min_baseline_depth_ratio, 0.02);
  EXPECT_EQ(t.vo.local_ba_max_fixed, 20);
  AgentConfig u;
  EXPECT_FALSE(LoadAgentConfig(Write("u.yaml", "vo:\n  triangulation_parallax_sigmas: -1\n"), &u, &error));
  EXPECT_NE(error.find("triangulation_parallax_sigmas"), std::string::npos) << error;
  EXPECT_FALSE(LoadAgentConfig(Write("v.yaml", "vo:\n  min_triangulation_parallax_deg: 0\n"), &u, &error));
  EXPECT_NE(error.find("min_triangulation_parallax_deg"), std::string::npos) << error;
  EXPECT_FALSE(LoadAgentConfig(Write("w.yaml", "vo:\n  min_baseline_depth_ratio: 1.5\n"), &u, &error));
  EXPECT_NE(error.find("min_baseline_depth_ratio"), std::string::npos) << error;
}

// The onboard template the ccm-agent package installs: one file per robot with its camera,
// calibration and the budgets for weak boards.
TEST(AgentConfig, OnboardTemplateLoads) {
  AgentConfig c;
  std::string error;
  ASSERT_TRUE(LoadAgentConfig(std::string(CCM_SOURCE_DIR) + "/deploy/config/agent-onboard.yaml", &c, &error)) << error;
  EXPECT_EQ(c.camera, "/dev/video0");
  EXPECT_EQ(c.calibration, "/etc/ccm-slam-dds/agents/camera.yaml");
  EXPECT_EQ(c.qos_file, "/etc/ccm-slam-dds/wifi-secure.xml");
  EXPECT_EQ(c.security_dir, "/etc/ccm-slam-dds/security") << "the onboard template is secure by default";
  EXPECT_FALSE(c.insecure);
  EXPECT_EQ(c.opencv_threads, 1);
  EXPECT_EQ(c.vo.local_ba_window, 7);
  EXPECT_LT(c.max_keyframes, AgentConfig().max_keyframes);
  EXPECT_FALSE(LoadAgentConfig(Write("threads.yaml", "opencv_threads: -1\n"), &c, &error));
  EXPECT_NE(error.find("opencv_threads"), std::string::npos) << error;
}

// The low-bandwidth example (docs/vo.md "Keyframe economy"): its sparse keyframe rule.
TEST(AgentConfig, LowBandwidthExampleLoads) {
  AgentConfig c;
  std::string error;
  ASSERT_TRUE(LoadAgentConfig(std::string(CCM_SOURCE_DIR) + "/deploy/config/agent-lowband.yaml", &c, &error)) << error;
  EXPECT_LT(c.vo.keyframe.tracked_ratio, AgentConfig().vo.keyframe.tracked_ratio);
  EXPECT_GT(c.vo.keyframe.max_interval_s, 0.0);
}

// The road profile (docs/vo.md "Initialization on the road"): what the VO test of later
// KITTI start frames runs with.
TEST(AgentConfig, RoadProfileCountsDistantPointsWithMoreFeatures) {
  AgentConfig c;
  std::string error;
  ASSERT_FALSE(c.vo.init_count_distant_points);
  ASSERT_TRUE(LoadAgentConfig(std::string(CCM_SOURCE_DIR) + "/deploy/config/agent-road.yaml", &c, &error)) << error;
  EXPECT_TRUE(c.vo.init_count_distant_points);
  EXPECT_EQ(c.vo.init_num_features, 4000);
  EXPECT_EQ(c.vo.init_min_homography_ratio, AgentConfig().vo.init_min_homography_ratio);
}

// The embedded profile (docs/deployment.md "Embedded profile"): less work per frame and per
// keyframe than the defaults, and late frames skipped.
TEST(AgentConfig, EmbeddedProfileDoesLessWorkAndSkipsLateFrames) {
  AgentConfig c;
  std::string error;
  ASSERT_TRUE(LoadAgentConfig(std::string(CCM_SOURCE_DIR) + "/deploy/config/agent-embedded.yaml", &c, &error)) << error;
  const AgentConfig d;
  EXPECT_LT(c.vo.orb.num_features, d.vo.orb.num_features);
  EXPECT_LT(c.vo.local_ba_window, d.vo.local_ba_window);
  EXPECT_EQ(c.opencv_threads, 1);
  EXPECT_TRUE(c.skip_late_frames);
  EXPECT_FALSE(d.skip_late_frames);
}

// ORB-SLAM's keyframe rule (a keyframe whenever fewer than 90 % of the reference's points
// are tracked, local BA over 10) is three keys away from the defaults (docs/configuration.md).
TEST(AgentConfig, OrbSlamKeyframeRuleCanBeRestored) {
  AgentConfig c;
  std::string error;
  ASSERT_GT(c.vo.keyframe.min_interval_s, 0.0) << "the default spaces keyframes";
  ASSERT_TRUE(LoadAgentConfig(Write("orbslam.yaml", "vo:\n  kf_min_interval_s: 0\n  kf_urgent_ratio: 0\n"
                                                    "  local_ba_window: 10\n  kf_reference: most_covisible\n"
                                                    "  kf_inlier_drop_ratio: 0\n  kf_turn_fov_share: 0\n"),
                              &c, &error))
      << error;
  EXPECT_EQ(c.vo.keyframe.min_interval_s, 0.0);
  EXPECT_EQ(c.vo.keyframe.urgent_ratio, 0.0);
  EXPECT_EQ(c.vo.local_ba_window, 10);
  EXPECT_EQ(c.vo.kf_reference, KeyframeReference::kMostCovisible);
  EXPECT_EQ(c.vo.keyframe.inlier_drop_ratio, 0.0);
  EXPECT_EQ(c.vo.keyframe.turn_fov_share, 0.0);
  EXPECT_EQ(c.vo.keyframe.tracked_ratio, AgentConfig().vo.keyframe.tracked_ratio);
  AgentConfig d;
  EXPECT_FALSE(LoadAgentConfig(Write("ref.yaml", "vo:\n  kf_reference: newest\n"), &d, &error));
  EXPECT_NE(error.find("kf_reference"), std::string::npos) << error;
  EXPECT_NE(error.find("most_covisible"), std::string::npos) << error;
  AgentConfig t;
  EXPECT_FALSE(LoadAgentConfig(Write("turn.yaml", "vo:\n  kf_turn_fov_share: -0.1\n"), &t, &error));
  EXPECT_NE(error.find("kf_turn_fov_share"), std::string::npos) << error;
}

}  // namespace
}  // namespace ccm::agent
