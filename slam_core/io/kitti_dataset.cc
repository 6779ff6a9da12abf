// KITTI odometry reader: image_0/%06d.png (left gray camera), calib.txt (P0 gives the
// rectified pinhole intrinsics), times.txt (seconds; the first N lines are used when the
// folder holds only N images), optional poses file (12 numbers per line).
#include <cstdio>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>

#include "slam_core/io/calibration_yaml.h"
#include "slam_core/io/dataset.h"
#include "slam_core/io/text_table.h"
#include "slam_core/io/trajectory_io.h"

namespace ccm {
namespace fs = std::filesystem;
namespace {

IoStatus ReadKittiP0(const std::string& path, CameraIntrinsics* intrinsics) {
  std::vector<io_internal::TextLine> lines;
  IoStatus status = io_internal::ReadTable(path, &lines);
  if (!status.ok()) return status;
  for (const io_internal::TextLine& line : lines) {
    if (line.fields.empty() || line.fields[0] != "P0:") continue;
    if (line.fields.size() != 13) {
      return IoStatus::Error(io_internal::Where(path, line.number) + ": P0 needs 12 numbers");
    }
    double p[12];
    if (!(status = io_internal::ParseDoubles(path, line, 1, 12, p)).ok()) return status;
    intrinsics->type = CameraType::kPinholeRadTan;
    intrinsics->fx = p[0];
    intrinsics->cx = p[2];
    intrinsics->fy = p[5];
    intrinsics->cy = p[6];
    intrinsics->distortion.assign(4, 0.0);  // KITTI images are rectified
    return IoStatus::Ok();
  }
  return IoStatus::Error(path + ": no 'P0:' line");
}

std::string KittiImagePath(const std::string& dir, size_t index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06zu.png", index);
  return (fs::path(dir) / "image_0" / name).string();
}

// Default poses file: <seq>/poses.txt, or <root>/poses/<seq>.txt for <root>/sequences/<seq>.
std::string DefaultPosesPath(const std::string& dir) {
  fs::path folder = fs::path(dir).lexically_normal();
  if (folder.filename().empty()) folder = folder.parent_path();
  if (fs::exists(folder / "poses.txt")) return (folder / "poses.txt").string();
  const fs::path standard =
      folder.parent_path().parent_path() / "poses" / (folder.filename().string() + ".txt");
  return fs::exists(standard) ? standard.string() : std::string();
}

IoStatus AttachKittiPoses(const std::string& path, std::vector<ImageEntry>* entries) {
  std::vector<SE3> poses;
  IoStatus status = ReadKittiPoses(path, &poses);
  if (!status.ok()) return status;
  if (poses.size() < entries->size()) {
    return IoStatus::Error(path + " has " + std::to_string(poses.size()) + " poses for " +
                           std::to_string(entries->size()) + " images");
  }
  for (size_t i = 0; i < entries->size(); ++i) (*entries)[i].world_from_cam_gt = poses[i];
  return IoStatus::Ok();
}

}  // namespace

std::unique_ptr<ImageListSource> OpenKittiDataset(const DatasetOptions& options, IoStatus* status) {
  const std::string& dir = options.path;
  CameraIntrinsics intrinsics;
  *status = options.calibration_path.empty()
                ? ReadKittiP0((fs::path(dir) / "calib.txt").string(), &intrinsics)
                : ReadCalibrationYaml(options.calibration_path, &intrinsics);
  if (!status->ok()) return nullptr;
  std::vector<ImageEntry> entries;
  for (size_t i = 0; fs::exists(KittiImagePath(dir, i)); ++i) entries.push_back({0, KittiImagePath(dir, i), {}});
  if (entries.empty()) {
    *status = IoStatus::Error("no images: " + KittiImagePath(dir, 0) + " not found");
    return nullptr;
  }
  std::vector<int64_t> stamps;
  const std::string times = (fs::path(dir) / "times.txt").string();
  if (!(*status = ReadKittiTimes(times, &stamps)).ok()) return nullptr;
  if (stamps.size() < entries.size()) {
    *status = IoStatus::Error(times + " has " + std::to_string(stamps.size()) + " times for " +
                              std::to_string(entries.size()) + " images");
    return nullptr;
  }
  for (size_t i = 0; i < entries.size(); ++i) entries[i].stamp_ns = stamps[i];
  if (options.calibration_path.empty()) {
    // calib.txt has no image size: take it from the first image header.
    const cv::Mat first = cv::imread(entries[0].path, cv::IMREAD_GRAYSCALE);
    if (first.empty()) {
      *status = IoStatus::Error("cannot read image " + entries[0].path);
      return nullptr;
    }
    intrinsics.width_px = first.cols;
    intrinsics.height_px = first.rows;
  }
  if (options.load_ground_truth) {
    const std::string poses =
        options.ground_truth_path.empty() ? DefaultPosesPath(dir) : options.ground_truth_path;
    if (!poses.empty() && !(*status = AttachKittiPoses(poses, &entries)).ok()) return nullptr;
  }
  return std::make_unique<ImageListSource>(intrinsics, std::move(entries));
}

}  // namespace ccm
