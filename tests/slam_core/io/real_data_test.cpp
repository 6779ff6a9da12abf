// Readers on the real excerpts in ../shared/data (not part of the repository: skipped when
// absent). See /work/shared/data/*/SOURCE.txt for what the numbers below come from.
#include <cstdlib>
#include <filesystem>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "slam_core/io/dataset.h"
#include "slam_core/io/trajectory_io.h"

namespace ccm {
namespace {

std::string DataDir(const std::string& name) {
  const char* env = std::getenv("CCM_DATA_DIR");
  return (std::filesystem::path(env ? env : CCM_SHARED_DATA_DIR) / name).string();
}

TEST(RealData, Kitti07First160) {
  const std::string dir = DataDir("kitti07_first160");
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " absent: real-data test skipped";
  DatasetOptions options;
  options.path = dir;
  options.ground_truth_path = dir + "/poses_07_first160_kitti.txt";
  IoStatus status;
  std::unique_ptr<ImageListSource> source = OpenKittiDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  EXPECT_EQ(source->size(), 160);  // times.txt has 1101 lines: only the first 160 are used
  const CameraIntrinsics& k = source->intrinsics();
  EXPECT_DOUBLE_EQ(k.fx, 707.0912);
  EXPECT_DOUBLE_EQ(k.fy, 707.0912);
  EXPECT_DOUBLE_EQ(k.cx, 601.8873);
  EXPECT_DOUBLE_EQ(k.cy, 183.1104);
  EXPECT_EQ(k.width_px, 1226);
  EXPECT_EQ(k.height_px, 370);
  EXPECT_EQ(source->entries()[1].stamp_ns, 103875200LL);
  const Trajectory gt = source->GroundTruth();
  ASSERT_EQ(gt.size(), 160u);
  EXPECT_LT(gt[0].world_from_cam.translation().norm(), 1e-9);
  // Line 2 of the poses file: t = (-4.596714e-03, -2.001524e-03, 9.154274e-02).
  EXPECT_NEAR(gt[1].world_from_cam.translation().z(), 9.154274e-02, 1e-12);
  double path_m = 0;
  for (size_t i = 1; i < gt.size(); ++i) {
    path_m += (gt[i].world_from_cam.translation() - gt[i - 1].world_from_cam.translation()).norm();
  }
  EXPECT_NEAR(path_m, 90.6, 0.5);  // SOURCE.txt: 90.6 m driven
  std::optional<Frame> frame = source->Next();
  ASSERT_TRUE(frame) << source->error();
  EXPECT_EQ(frame->image.cols, 1226);
  EXPECT_EQ(frame->image.type(), CV_8UC1);
}

TEST(RealData, Ntsd150Euroc) {
  const std::string dir = DataDir("ntsd150_euroc");
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " absent: real-data test skipped";
  DatasetOptions options;
  options.path = dir;
  DatasetFormat format;
  ASSERT_TRUE(DetectDatasetFormat(dir, &format).ok());
  EXPECT_EQ(format, DatasetFormat::kEuroc);
  IoStatus status;
  std::unique_ptr<ImageListSource> source = OpenEurocDataset(options, &status);
  ASSERT_TRUE(source) << status.message();
  EXPECT_EQ(source->size(), 150);
  const CameraIntrinsics& k = source->intrinsics();
  EXPECT_DOUBLE_EQ(k.fx, 615.0);
  EXPECT_DOUBLE_EQ(k.cx, 320.0);
  EXPECT_EQ(k.width_px, 640);
  EXPECT_EQ(k.height_px, 480);
  EXPECT_EQ(source->GroundTruth().size(), 150u);  // every frame has its pose
  double path_m = 0;
  const Trajectory gt = source->GroundTruth();
  for (size_t i = 1; i < gt.size(); ++i) {
    path_m += (gt[i].world_from_cam.translation() - gt[i - 1].world_from_cam.translation()).norm();
  }
  EXPECT_NEAR(path_m, 3.77, 0.05);  // SOURCE.txt: ~377 cm
  // Colour JPEG data in .png names: decoded by content, delivered as 8-bit gray.
  std::optional<Frame> frame = source->Next();
  ASSERT_TRUE(frame) << source->error();
  EXPECT_EQ(frame->image.type(), CV_8UC1);
  EXPECT_EQ(frame->image.cols, 640);
}

}  // namespace
}  // namespace ccm
