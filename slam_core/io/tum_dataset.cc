// TUM RGB-D reader: rgb.txt ("timestamp filename", seconds), groundtruth.txt (TUM trajectory).
// The dataset ships no calibration file, so it comes from the caller or the published fr1/2/3
// values chosen by the folder name.
#include <filesystem>
#include <regex>

#include "slam_core/io/calibration_yaml.h"
#include "slam_core/io/dataset.h"
#include "slam_core/io/text_table.h"
#include "slam_core/io/trajectory_io.h"

namespace ccm {
namespace fs = std::filesystem;

std::optional<CameraIntrinsics> TumDefaultIntrinsics(int freiburg) {
  // https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats (d0..d4 = k1 k2 p1 p2 k3).
  CameraIntrinsics k;
  k.type = CameraType::kPinholeRadTan;
  k.width_px = 640;
  k.height_px = 480;
  switch (freiburg) {
    case 1:
      k.fx = 517.3, k.fy = 516.5, k.cx = 318.6, k.cy = 255.3;
      k.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
      return k;
    case 2:
      k.fx = 520.9, k.fy = 521.0, k.cx = 325.1, k.cy = 249.7;
      k.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
      return k;
    case 3:
      k.fx = 535.4, k.fy = 539.2, k.cx = 320.1, k.cy = 247.6;
      k.distortion = {0.0, 0.0, 0.0, 0.0};
      return k;
    default:
      return std::nullopt;
  }
}

namespace {

IoStatus TumIntrinsics(const DatasetOptions& options, CameraIntrinsics* intrinsics) {
  if (!options.calibration_path.empty()) return ReadCalibrationYaml(options.calibration_path, intrinsics);
  fs::path folder = fs::path(options.path).lexically_normal();
  if (folder.filename().empty()) folder = folder.parent_path();  // trailing slash
  const std::string name = folder.filename().string();
  std::smatch match;
  if (std::regex_search(name, match, std::regex("(freiburg|fr)([123])"))) {
    *intrinsics = *TumDefaultIntrinsics(match[2].str()[0] - '0');
    return IoStatus::Ok();
  }
  return IoStatus::Error(options.path + ": TUM RGB-D folder name does not say freiburg1/2/3; give a "
                         "calibration YAML (DatasetOptions::calibration_path)");
}

IoStatus ReadRgbList(const std::string& dir, std::vector<ImageEntry>* entries) {
  const std::string list = (fs::path(dir) / "rgb.txt").string();
  std::vector<io_internal::TextLine> lines;
  IoStatus status = io_internal::ReadTable(list, &lines);
  if (!status.ok()) return status;
  for (const io_internal::TextLine& line : lines) {
    const std::string where = io_internal::Where(list, line.number);
    if (line.fields.size() != 2) {
      return IoStatus::Error(where + ": expected 'timestamp filename', found " +
                             std::to_string(line.fields.size()) + " fields");
    }
    ImageEntry entry;
    if (!io_internal::ParseSecondsToNs(line.fields[0], &entry.stamp_ns)) {
      return IoStatus::Error(where + ": bad timestamp '" + line.fields[0] + "'");
    }
    if (!entries->empty() && entry.stamp_ns <= entries->back().stamp_ns) {
      return IoStatus::Error(where + ": timestamps must increase");
    }
    entry.path = (fs::path(dir) / line.fields[1]).string();
    if (!fs::exists(entry.path)) return IoStatus::Error(where + ": image not found: " + entry.path);
    entries->push_back(std::move(entry));
  }
  if (entries->empty()) return IoStatus::Error(list + " lists no images");
  return IoStatus::Ok();
}

}  // namespace

std::unique_ptr<ImageListSource> OpenTumRgbdDataset(const DatasetOptions& options, IoStatus* status) {
  CameraIntrinsics intrinsics;
  *status = TumIntrinsics(options, &intrinsics);
  if (!status->ok()) return nullptr;
  std::vector<ImageEntry> entries;
  *status = ReadRgbList(options.path, &entries);
  if (!status->ok()) return nullptr;
  if (options.load_ground_truth) {
    std::string gt_path = options.ground_truth_path;
    if (gt_path.empty()) gt_path = (fs::path(options.path) / "groundtruth.txt").string();
    if (!options.ground_truth_path.empty() || fs::exists(gt_path)) {
      Trajectory gt;
      *status = ReadTumTrajectory(gt_path, &gt);
      if (!status->ok()) return nullptr;
      AttachGroundTruth(gt, static_cast<int64_t>(options.gt_max_dt_s * 1e9), &entries);
    }
  }
  return std::make_unique<ImageListSource>(intrinsics, std::move(entries));
}

}  // namespace ccm
