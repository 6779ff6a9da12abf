#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include "slam_core/io/dataset.h"
#include "tests/sim/euroc_writer.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/sim_test_util.h"

namespace ccm::sim {
namespace {

namespace fs = std::filesystem;
using testing::SharedSim;

std::vector<std::vector<std::string>> ReadCsv(const fs::path& path, std::string* header) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  std::getline(in, *header);
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

class EurocWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ccm_sim_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(EurocWriterTest, WritesImagesGroundTruthAndSensorYaml) {
  const auto sim = SharedSim("hall3");
  const int agent = 1;
  std::int64_t last_progress = 0;
  ASSERT_EQ(WriteEurocAgent(*sim, agent, dir_.string(), 6, [&](std::int64_t d, std::int64_t) { last_progress = d; }),
            "");
  EXPECT_EQ(last_progress, 6);
  const fs::path mav0 = dir_ / "agent1" / "mav0";
  std::string header;
  const auto images = ReadCsv(mav0 / "cam0" / "data.csv", &header);
  EXPECT_EQ(header, "#timestamp [ns],filename");
  ASSERT_EQ(images.size(), 6u);
  const auto gt = ReadCsv(mav0 / "state_groundtruth_estimate0" / "data.csv", &header);
  EXPECT_EQ(header, EurocGroundTruthHeader());
  ASSERT_EQ(gt.size(), 6u);
  for (std::int64_t i = 0; i < 6; ++i) {
    const std::int64_t stamp = sim->StampNs(agent, i);
    EXPECT_EQ(images[i][0], std::to_string(stamp));
    EXPECT_EQ(images[i][1], std::to_string(stamp) + ".png");
    const cv::Mat img = cv::imread((mav0 / "cam0" / "data" / images[i][1]).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(img.type(), CV_8UC1);
    EXPECT_EQ(cv::norm(img, sim->RenderFrame(agent, i), cv::NORM_L1), 0.0);
    ASSERT_EQ(gt[i].size(), 17u);
    EXPECT_EQ(gt[i][0], std::to_string(stamp));
    const Eigen::Vector3d p(std::stod(gt[i][1]), std::stod(gt[i][2]), std::stod(gt[i][3]));
    const Eigen::Quaterniond q(std::stod(gt[i][4]), std::stod(gt[i][5]), std::stod(gt[i][6]), std::stod(gt[i][7]));
    const SE3 truth = sim->WorldFromCam(agent, i);
    EXPECT_LT((p - truth.translation()).norm(), 1e-8);
    EXPECT_LT(q.angularDistance(truth.rotation()), 1e-9);
    const Eigen::Vector3d v(std::stod(gt[i][8]), std::stod(gt[i][9]), std::stod(gt[i][10]));
    EXPECT_GT(v.norm(), 0.3);
  }
  EXPECT_EQ(sim->StampNs(agent, 1) - sim->StampNs(agent, 0), 50'000'000);

  const YAML::Node sensor = YAML::LoadFile((mav0 / "cam0" / "sensor.yaml").string());
  const CameraIntrinsics& c = sim->scenario().camera;
  EXPECT_EQ(sensor["camera_model"].as<std::string>(), "pinhole");
  EXPECT_EQ(sensor["distortion_model"].as<std::string>(), "radial-tangential");
  EXPECT_EQ(sensor["resolution"][0].as<int>(), 752);
  EXPECT_EQ(sensor["resolution"][1].as<int>(), 480);
  const auto k = sensor["intrinsics"].as<std::vector<double>>();
  EXPECT_EQ(k, (std::vector<double>{c.fx, c.fy, c.cx, c.cy}));
  EXPECT_EQ(sensor["distortion_coefficients"].as<std::vector<double>>(), c.distortion);
  const auto t_bs = sensor["T_BS"]["data"].as<std::vector<double>>();
  ASSERT_EQ(t_bs.size(), 16u);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(t_bs[i], i % 5 == 0 ? 1.0 : 0.0);
  EXPECT_EQ(sensor["rate_hz"].as<double>(), 20.0);
}

// The project's EuRoC reader (ccm_io) reads the folders back: same images, stamps,
// camera poses and calibration, for both camera models.
TEST_F(EurocWriterTest, RoundTripsThroughTheEurocReader) {
  for (const bool fisheye : {false, true}) {
    Scenario scenario = testing::BuiltinOrDie("hall3");
    if (fisheye) scenario.camera = FisheyeCamera();
    std::string error;
    const auto sim = Simulation::Create(scenario, &error, SharedSim("hall3")->world());
    ASSERT_TRUE(sim) << error;
    const fs::path out = dir_ / (fisheye ? "fisheye" : "pinhole");
    ASSERT_EQ(WriteEurocAgent(*sim, 0, out.string(), 4), "");
    IoStatus status;
    const auto source = OpenDataset((out / "agent0").string(), DatasetFormat::kAuto, &status);
    ASSERT_TRUE(source) << status.message();
    const CameraIntrinsics& read = source->intrinsics();
    EXPECT_EQ(read.type, scenario.camera.type);
    EXPECT_EQ(read.width_px, scenario.camera.width_px);
    EXPECT_DOUBLE_EQ(read.fx, scenario.camera.fx);
    EXPECT_DOUBLE_EQ(read.cy, scenario.camera.cy);
    EXPECT_EQ(read.distortion, scenario.camera.distortion);
    EXPECT_EQ(source->size(), 4);
    for (std::int64_t i = 0; i < 4; ++i) {
      const auto frame = source->Next();
      ASSERT_TRUE(frame) << source->error();
      EXPECT_EQ(frame->stamp_ns, sim->StampNs(0, i));
      EXPECT_EQ(cv::norm(frame->image, sim->RenderFrame(0, i), cv::NORM_L1), 0.0);
      ASSERT_TRUE(frame->world_from_cam_gt);
      const SE3 truth = sim->WorldFromCam(0, i);
      EXPECT_LT((frame->world_from_cam_gt->translation() - truth.translation()).norm(), 1e-8);
      EXPECT_LT(frame->world_from_cam_gt->rotation().angularDistance(truth.rotation()), 1e-9);
    }
    EXPECT_FALSE(source->Next());
    EXPECT_EQ(source->error(), "");
  }
}

TEST(SensorYaml, FisheyeIsPinholeWithEquidistantDistortion) {
  const YAML::Node y = YAML::Load(EurocSensorYaml(FisheyeCamera(), 20.0));
  EXPECT_EQ(y["camera_model"].as<std::string>(), "pinhole");
  EXPECT_EQ(y["distortion_model"].as<std::string>(), "equidistant");
  EXPECT_EQ(y["distortion_coefficients"].as<std::vector<double>>().size(), 4u);
}

TEST(SimFrameSource, DeliversTheRenderedFramesWithGroundTruth) {
  const auto sim = SharedSim("hall3");
  SimFrameSource source(sim, 2, 10, 5, 3);
  EXPECT_EQ(source.size(), 3);
  EXPECT_EQ(source.intrinsics().width_px, 752);
  for (std::int64_t index : {10, 15, 20}) {
    const auto f = source.Next();
    ASSERT_TRUE(f);
    EXPECT_EQ(f->stamp_ns, sim->StampNs(2, index));
    EXPECT_EQ(cv::norm(f->image, sim->RenderFrame(2, index), cv::NORM_L1), 0.0);
    ASSERT_TRUE(f->world_from_cam_gt);
    EXPECT_LT((f->world_from_cam_gt->translation() - sim->WorldFromCam(2, index).translation()).norm(), 1e-12);
    EXPECT_EQ(f->source_name, "sim:agent2:" + std::to_string(index));
  }
  EXPECT_FALSE(source.Next());
  EXPECT_EQ(source.error(), "");
  EXPECT_EQ(SimFrameSource(sim, 0).size(), sim->NumFrames(0));
  SimFrameSource bad(sim, 7);
  EXPECT_EQ(bad.size(), 0);
  EXPECT_FALSE(bad.Next());
  EXPECT_NE(bad.error().find("no agent 7"), std::string::npos);
}

}  // namespace
}  // namespace ccm::sim
