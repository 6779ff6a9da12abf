#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "slam_core/io/dataset.h"
#include "slam_core/io/trajectory_io.h"
#include "test_files.h"

namespace ccm {
namespace {

using test::ScratchDir;
using test::WriteText;

constexpr char kSensorYaml[] = R"(%YAML:1.0
sensor_type: camera
T_BS:
  cols: 4
  rows: 4
  data: [0.0, -1.0, 0.0, 0.1,
         1.0,  0.0, 0.0, 0.2,
         0.0,  0.0, 1.0, 0.3,
         0.0,  0.0, 0.0, 1.0]
rate_hz: 20
resolution: [32, 24]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375]
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
)";

void WriteImage(const std::string& path, int w, int h, int value) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  ASSERT_TRUE(cv::imwrite(path, cv::Mat(h, w, CV_8UC3, cv::Scalar(value, value, value))));
}

// EuRoC folder with 4 frames at 20 Hz and body ground truth at 200 Hz (+1 ms) that stops
// before the last frame.
Trajectory MakeEuroc(const ScratchDir& dir) {
  const std::string cam = dir / "mav0/cam0";
  WriteText(cam + "/sensor.yaml", kSensorYaml);
  std::string csv = "#timestamp [ns],filename\n";
  for (int i = 0; i < 4; ++i) {
    const std::string ns = std::to_string(1000000000LL + i * 50000000LL);
    csv += ns + "," + ns + ".png\n";
    WriteImage(cam + "/data/" + ns + ".png", 32, 24, 40 * i);
  }
  WriteText(cam + "/data.csv", csv);
  Trajectory body = test::RandomTrajectory(30, 7, 1000000000LL + 1000000LL, 5000000LL);
  EXPECT_TRUE(WriteEurocTrajectory(dir / "mav0/state_groundtruth_estimate0/data.csv", body).ok());
  return body;
}

TEST(EurocDataset, ReadsCalibrationFramesAndCameraGroundTruth) {
  ScratchDir dir;
  const Trajectory body = MakeEuroc(dir);
  DatasetOptions options;
  options.path = dir.str();
  options.gt_max_dt_s = 0.002;
  IoStatus status;
  std::unique_ptr<ImageListSource> source = OpenEurocDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  const CameraIntrinsics& k = source->intrinsics();
  EXPECT_EQ(k.type, CameraType::kPinholeRadTan);
  EXPECT_EQ(k.width_px, 32);
  EXPECT_EQ(k.height_px, 24);
  EXPECT_DOUBLE_EQ(k.fx, 458.654);
  EXPECT_DOUBLE_EQ(k.cy, 248.375);
  ASSERT_EQ(k.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(k.distortion[3], 1.76187114e-05);
  ASSERT_EQ(source->size(), 4);

  Eigen::Matrix3d R;
  R << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const SE3 body_from_cam(R, Eigen::Vector3d(0.1, 0.2, 0.3));
  for (int i = 0; i < 4; ++i) {
    std::optional<Frame> frame = source->Next();
    ASSERT_TRUE(frame) << source->error();
    EXPECT_EQ(frame->image.type(), CV_8UC1);
    EXPECT_EQ(frame->stamp_ns, 1000000000LL + i * 50000000LL);
    if (i == 3) {  // ground truth ends at 1.146 s, the frame is at 1.15 s: no pose
      EXPECT_FALSE(frame->world_from_cam_gt);
      continue;
    }
    ASSERT_TRUE(frame->world_from_cam_gt);
    const SE3 expected = body[10 * i].world_from_cam * body_from_cam;  // nearest: 1 ms later
    EXPECT_LT((frame->world_from_cam_gt->translation() - expected.translation()).norm(), 1e-12);
    EXPECT_LT(frame->world_from_cam_gt->rotation().angularDistance(expected.rotation()), 1e-12);
  }
  EXPECT_FALSE(source->Next());
  EXPECT_TRUE(source->error().empty());

  // The folder as a trajectory (ccm_eval --gt DIR) gives the same camera poses.
  Trajectory gt;
  ASSERT_TRUE(ReadTrajectory(dir.str(), {}, &gt).ok());
  ASSERT_EQ(gt.size(), body.size());
  EXPECT_LT((gt[10].world_from_cam.translation() -
             (body[10].world_from_cam * body_from_cam).translation()).norm(), 1e-12);
}

TEST(EurocDataset, EquidistantModelAndErrors) {
  ScratchDir dir;
  MakeEuroc(dir);
  std::string yaml = kSensorYaml;
  yaml.replace(yaml.find("radial-tangential"), 17, "equidistant");
  WriteText(dir / "mav0/cam0/sensor.yaml", yaml);
  DatasetOptions options;
  options.path = dir / "mav0";  // the mav0 folder itself works too
  IoStatus status;
  std::unique_ptr<FrameSource> source = OpenDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  EXPECT_EQ(source->intrinsics().type, CameraType::kFisheyeEquidistant);

  WriteText(dir / "mav0/cam0/data.csv", "#ts,file\n1000000000,1000000000.png\nabc,x.png\n");
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("data.csv:3: timestamp 'abc'"), std::string::npos)
      << status.message();
  WriteText(dir / "mav0/cam0/data.csv", "1000000000,missing.png\n");
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("data.csv:1: image not found"), std::string::npos)
      << status.message();
  std::filesystem::remove(dir / "mav0/cam0/sensor.yaml");
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("cannot open"), std::string::npos) << status.message();
  yaml.replace(yaml.find("[32, 24]"), 8, "[32]");
  WriteText(dir / "mav0/cam0/sensor.yaml", yaml);
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("'resolution' must have 2 numbers"), std::string::npos)
      << status.message();
}

TEST(EurocDataset, ImageSizeMismatchIsReportedByNext) {
  ScratchDir dir;
  MakeEuroc(dir);
  WriteImage(dir / "mav0/cam0/data/1000000000.png", 16, 24, 0);
  DatasetOptions options;
  options.path = dir.str();
  IoStatus status;
  std::unique_ptr<FrameSource> source = OpenDataset(options, &status);
  ASSERT_TRUE(source);
  EXPECT_FALSE(source->Next());
  EXPECT_NE(source->error().find("is 16x24 but the calibration says 32x24"), std::string::npos)
      << source->error();
}

TEST(TumDataset, DefaultFreiburgCalibrationOrYaml) {
  ScratchDir root;
  const std::string dir = root / "rgbd_dataset_freiburg1_xyz";
  WriteText(dir + "/rgb.txt", "# color images\n1305031102.175304 rgb/a.png\n1305031102.211214 rgb/b.png\n");
  WriteImage(dir + "/rgb/a.png", 640, 480, 10);
  WriteImage(dir + "/rgb/b.png", 640, 480, 20);
  WriteText(dir + "/groundtruth.txt",
            "# ground truth\n1305031102.1758 1.0 2.0 3.0 0 0 0 1\n1305031102.2000 4 5 6 0 0 0 1\n");
  DatasetOptions options;
  options.path = dir + "/";
  IoStatus status;
  std::unique_ptr<ImageListSource> source = OpenTumRgbdDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  EXPECT_DOUBLE_EQ(source->intrinsics().fx, 517.3);
  EXPECT_EQ(source->intrinsics().distortion.size(), 5u);
  ASSERT_EQ(source->size(), 2);
  EXPECT_EQ(source->entries()[0].stamp_ns, 1305031102175304000LL);
  ASSERT_TRUE(source->entries()[0].world_from_cam_gt);
  EXPECT_DOUBLE_EQ(source->entries()[0].world_from_cam_gt->translation().x(), 1.0);
  EXPECT_FALSE(source->entries()[1].world_from_cam_gt);  // 11 ms from the nearest pose

  WriteText(root / "calib.yaml", "%YAML:1.0\nCamera.fx: 500\nCamera.fy: 501\nCamera.cx: 320\n"
                                 "Camera.cy: 240\nCamera.width: 640\nCamera.height: 480\nCamera.k1: 0.1\n");
  options.calibration_path = root / "calib.yaml";
  source = OpenTumRgbdDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  EXPECT_DOUBLE_EQ(source->intrinsics().fy, 501.0);
  EXPECT_DOUBLE_EQ(source->intrinsics().distortion[0], 0.1);

  std::filesystem::rename(dir, root / "my_sequence");
  options.path = root / "my_sequence";
  options.calibration_path.clear();
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("does not say freiburg1/2/3"), std::string::npos) << status.message();
}

TEST(KittiDataset, ReadsImagesCalibTimesAndPoses) {
  ScratchDir dir;
  for (int i = 0; i < 3; ++i) WriteImage(dir / ("image_0/00000" + std::to_string(i) + ".png"), 40, 12, i);
  WriteText(dir / "calib.txt", "P0: 7.07e+02 0 6.01e+02 0 0 7.08e+02 1.83e+02 0 0 0 1 0\n");
  WriteText(dir / "times.txt", "0.0\n1.0e-01\n2.0e-01\n3.0e-01\n");
  const Trajectory poses = test::RandomTrajectory(3, 9);
  ASSERT_TRUE(WriteKittiPoses(dir / "poses.txt", poses).ok());
  DatasetOptions options;
  options.path = dir.str();
  DatasetFormat format;
  ASSERT_TRUE(DetectDatasetFormat(dir.str(), &format).ok());
  EXPECT_EQ(format, DatasetFormat::kKitti);
  IoStatus status;
  std::unique_ptr<ImageListSource> source = OpenKittiDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  EXPECT_EQ(source->size(), 3);
  EXPECT_EQ(source->intrinsics().width_px, 40);
  EXPECT_DOUBLE_EQ(source->intrinsics().fy, 708.0);
  EXPECT_EQ(source->entries()[2].stamp_ns, 200000000LL);
  ASSERT_EQ(source->GroundTruth().size(), 3u);
  EXPECT_LT((source->entries()[2].world_from_cam_gt->translation() -
             poses[2].world_from_cam.translation()).norm(), 1e-12);

  WriteText(dir / "times.txt", "0.0\n0.1\n");
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("has 2 times for 3 images"), std::string::npos) << status.message();
}

TEST(OpenDataset, UnknownLayoutAndMissingFolder) {
  ScratchDir dir;
  DatasetOptions options;
  options.path = dir.str();
  IoStatus status;
  EXPECT_FALSE(OpenDataset(options, &status));
  EXPECT_NE(status.message().find("unknown dataset layout"), std::string::npos);
  EXPECT_FALSE(OpenDataset(dir / "nope", DatasetFormat::kKitti, &status));
  EXPECT_NE(status.message().find("not found"), std::string::npos);
}

}  // namespace
}  // namespace ccm
