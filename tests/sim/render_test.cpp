#include <cmath>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "tests/sim/sim_test_util.h"

namespace ccm::sim {
namespace {

using testing::BuiltinOrDie;
using testing::SharedSim;

// A flat grey room with a small bright square marker on the far wall (y = 10), and
// optionally a box hiding it from a camera at y = 6.
std::string MarkerScene(bool with_occluder) {
  std::string yaml = R"(name: marker
render: {read_noise_dn: 0, shot_noise_gain: 0, vignetting: 0}
exposure: {variation: 0}
objects:
  - {type: room, min: [0, 0, 0], max: [10, 10, 4], style: flat, grey: 60}
  - {type: panel, center: [5, 9.99, 1.7], normal: [0, -1, 0], size: [0.06, 0.06], style: flat, grey: 250}
)";
  if (with_occluder) yaml += "  - {type: box, center: [5.1, 8], size: [0.5, 0.5, 3], style: flat, grey: 100}\n";
  yaml += "agents:\n  - {name: a, duration_s: 1, waypoints: [[1, 1, 1], [2, 1, 1], [2, 2, 1]]}\n";
  return yaml;
}

// Camera at `c` looking along +y, then yawed/pitched by the given angles.
SE3 LookingNorth(const Eigen::Vector3d& c, double yaw_deg, double pitch_deg) {
  Eigen::Matrix3d R;
  R << Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY();
  R = Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()) * R *
      Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitX());
  return SE3(R, c);
}

std::unique_ptr<Simulation> MarkerSim(bool occluder) {
  std::string error;
  auto scenario = ParseScenarioYaml(MarkerScene(occluder), "marker", &error);
  EXPECT_TRUE(scenario) << error;
  auto sim = Simulation::Create(*scenario, &error);
  EXPECT_TRUE(sim) << error;
  return sim;
}

TEST(Render, SameScenarioAndSeedGiveByteIdenticalImages) {
  std::string error;
  auto other = Simulation::Create(BuiltinOrDie("hall3"), &error);
  ASSERT_TRUE(other) << error;
  const auto shared = SharedSim("hall3");
  for (int agent = 0; agent < 3; ++agent)
    for (std::int64_t i : {0, 333}) {
      const cv::Mat a = shared->RenderFrame(agent, i), b = other->RenderFrame(agent, i);
      ASSERT_EQ(a.type(), CV_8UC1);
      EXPECT_EQ(cv::norm(a, b, cv::NORM_L1), 0.0) << "agent " << agent << " frame " << i;
    }
  Scenario reseeded = BuiltinOrDie("hall3");
  reseeded.seed = 99;
  auto third = Simulation::Create(reseeded, &error);
  EXPECT_GT(cv::norm(shared->RenderFrame(0, 10), third->RenderFrame(0, 10), cv::NORM_L1), 1e6);
}

TEST(Render, MotionBlurIsDeterministicToo) {
  Scenario s = BuiltinOrDie("hall3");
  s.render.motion_blur_samples = 3;
  s.render.exposure_time_s = 0.02;
  std::string error;
  auto sim = Simulation::Create(s, &error, SharedSim("hall3")->world());
  ASSERT_TRUE(sim) << error;
  const cv::Mat a = sim->RenderFrame(1, 100);
  EXPECT_EQ(cv::norm(a, sim->RenderFrame(1, 100), cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(a, SharedSim("hall3")->RenderFrame(1, 100), cv::NORM_L1), 0.0);
}

void ExpectRayCastsReproject(const Simulation& sim, int agent, std::int64_t index) {
  const SE3 world_from_cam = sim.WorldFromCam(agent, index);
  const CameraModel& cam = sim.renderer().camera();
  cv::Mat depth, surface;
  sim.renderer().RenderDepth(world_from_cam, &depth, &surface);
  int checked = 0;
  for (double v = 3.3; v < cam.height(); v += 37.1)
    for (double u = 2.7; u < cam.width(); u += 41.3) {
      const auto hit = sim.renderer().CastRay(world_from_cam, Eigen::Vector2d(u, v));
      if (!hit) continue;
      Eigen::Vector2d uv;
      ASSERT_TRUE(cam.Project(world_from_cam.inverse() * hit->point_w, &uv));
      EXPECT_NEAR(uv.x(), u, 1e-6);
      EXPECT_NEAR(uv.y(), v, 1e-6);
      // The depth map at the nearest integer pixel agrees with an exact cast there.
      const int x = static_cast<int>(std::lround(u)), y = static_cast<int>(std::lround(v));
      const auto exact = sim.renderer().CastRay(world_from_cam, Eigen::Vector2d(x, y));
      ASSERT_TRUE(exact);
      EXPECT_EQ(surface.at<int>(y, x), exact->surface);
      EXPECT_NEAR(depth.at<float>(y, x), exact->depth_m, 1e-4 * exact->depth_m);
      ++checked;
    }
  EXPECT_GT(checked, 100);
}

TEST(Render, RayCastPointsProjectBackToTheirPixel) {
  ExpectRayCastsReproject(*SharedSim("hall3"), 0, 250);
  ExpectRayCastsReproject(*SharedSim("hall3"), 2, 900);
}

TEST(Render, FisheyeRaysProjectBackAndImageIsValid) {
  Scenario s = BuiltinOrDie("hall3");
  s.camera = FisheyeCamera();
  std::string error;
  auto sim = Simulation::Create(s, &error, SharedSim("hall3")->world());
  ASSERT_TRUE(sim) << error;
  ExpectRayCastsReproject(*sim, 1, 40);
  const cv::Mat img = sim->RenderFrame(1, 40);
  EXPECT_GT(cv::mean(img)[0], 40.0);
}

TEST(Render, MarkerAppearsAtItsProjectedPixel) {
  auto sim = MarkerSim(false);
  const Eigen::Vector3d marker(5, 9.99, 1.7);
  const CameraModel& cam = sim->renderer().camera();
  for (const auto& [yaw, pitch] : std::vector<std::pair<double, double>>{{0, 0}, {20, 10}, {-25, -12}, {30, -18}}) {
    const SE3 pose = LookingNorth(Eigen::Vector3d(5.3, 6.0, 1.5), yaw, pitch);
    Eigen::Vector2d expected;
    ASSERT_TRUE(cam.Project(pose.inverse() * marker, &expected));
    ASSERT_TRUE(cam.InImage(expected, 10));
    const cv::Mat img = sim->renderer().Render(pose, 1.0f, 0);
    double sw = 0, su = 0, sv = 0;
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x)
        if (img.at<uchar>(y, x) > 155) {
          const double w = img.at<uchar>(y, x) - 60.0;
          sw += w;
          su += w * x;
          sv += w * y;
        }
    ASSERT_GT(sw, 0.0) << "marker not visible at yaw " << yaw << " pitch " << pitch;
    EXPECT_LT((Eigen::Vector2d(su / sw, sv / sw) - expected).norm(), 1.0) << "yaw " << yaw << " pitch " << pitch;
  }
}

TEST(Render, OccludedMarkerIsHidden) {
  auto sim = MarkerSim(true);
  const SE3 pose = LookingNorth(Eigen::Vector3d(5.0, 6.0, 1.7), 0, 0);
  const cv::Mat img = sim->renderer().Render(pose, 1.0f, 0);
  double max_value = 0;
  cv::minMaxLoc(img, nullptr, &max_value);
  EXPECT_LT(max_value, 155);
  const auto hit = sim->renderer().CastRay(pose, Eigen::Vector2d(367.215, 248.375));
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->depth_m, 1.75, 0.01);  // the box's near face at y = 7.75
}

TEST(Render, OrbFindsEnoughKeypointsOnHall3) {
  const auto sim = SharedSim("hall3");
  cv::Ptr<cv::ORB> orb = cv::ORB::create(1000);
  int frames = 0, good = 0;
  for (int agent = 0; agent < sim->num_agents(); ++agent)
    for (std::int64_t i = 0; i < sim->NumFrames(agent); i += 100) {
      std::vector<cv::KeyPoint> kp;
      orb->detect(sim->RenderFrame(agent, i), kp);
      ++frames;
      good += kp.size() >= 800 ? 1 : 0;
    }
  EXPECT_GE(frames, 40);
  EXPECT_GE(good, 0.95 * frames) << good << " of " << frames << " frames with >= 800 ORB keypoints";
}

}  // namespace
}  // namespace ccm::sim
