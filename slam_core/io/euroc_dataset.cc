// EuRoC ASL reader: mav0/<camera>/data.csv (ns,filename), images in mav0/<camera>/data/,
// mav0/<camera>/sensor.yaml, ground truth mav0/state_groundtruth_estimate0/data.csv.
#include <filesystem>

#include "slam_core/io/calibration_yaml.h"
#include "slam_core/io/dataset.h"
#include "slam_core/io/text_table.h"
#include "slam_core/io/trajectory_io.h"

namespace ccm {
namespace fs = std::filesystem;

std::optional<std::string> EurocMavFolder(const std::string& path) {
  if (fs::is_directory(fs::path(path) / "mav0")) return (fs::path(path) / "mav0").string();
  if (fs::is_directory(fs::path(path) / "cam0") ||
      fs::is_directory(fs::path(path) / "state_groundtruth_estimate0")) {
    return path;
  }
  return std::nullopt;
}

namespace {

IoStatus ReadEurocImageList(const std::string& csv, const std::string& image_dir,
                            std::vector<ImageEntry>* entries) {
  std::vector<io_internal::TextLine> lines;
  IoStatus status = io_internal::ReadTable(csv, &lines);
  if (!status.ok()) return status;
  int64_t previous = 0;
  for (const io_internal::TextLine& line : lines) {
    const std::string where = io_internal::Where(csv, line.number);
    if (line.fields.size() != 2) {
      return IoStatus::Error(where + ": expected 'timestamp_ns,filename', found " +
                             std::to_string(line.fields.size()) + " fields");
    }
    ImageEntry entry;
    if (!io_internal::ParseInt64(line.fields[0], &entry.stamp_ns)) {
      return IoStatus::Error(where + ": timestamp '" + line.fields[0] +
                             "' is not an integer number of nanoseconds");
    }
    if (!entries->empty() && entry.stamp_ns <= previous) {
      return IoStatus::Error(where + ": timestamps must increase");
    }
    previous = entry.stamp_ns;
    entry.path = (fs::path(image_dir) / line.fields[1]).string();
    if (!fs::exists(entry.path)) return IoStatus::Error(where + ": image not found: " + entry.path);
    entries->push_back(std::move(entry));
  }
  if (entries->empty()) return IoStatus::Error(csv + " lists no images");
  return IoStatus::Ok();
}

}  // namespace

std::unique_ptr<ImageListSource> OpenEurocDataset(const DatasetOptions& options, IoStatus* status) {
  const std::optional<std::string> mav = EurocMavFolder(options.path);
  if (!mav) {
    *status = IoStatus::Error(options.path + " is not a EuRoC dataset (no mav0/ or cam0/ folder)");
    return nullptr;
  }
  const fs::path cam_dir = fs::path(*mav) / options.camera;
  EurocCameraCalibration calibration;
  *status = ReadEurocSensorYaml((cam_dir / "sensor.yaml").string(), &calibration);
  if (status->ok() && !options.calibration_path.empty()) {
    *status = ReadCalibrationYaml(options.calibration_path, &calibration.intrinsics);
  }
  if (!status->ok()) return nullptr;
  std::vector<ImageEntry> entries;
  *status = ReadEurocImageList((cam_dir / "data.csv").string(), (cam_dir / "data").string(), &entries);
  if (!status->ok()) return nullptr;

  if (options.load_ground_truth) {
    std::string gt_path = options.ground_truth_path;
    if (gt_path.empty()) {
      gt_path = (fs::path(*mav) / "state_groundtruth_estimate0" / "data.csv").string();
    }
    if (!options.ground_truth_path.empty() || fs::exists(gt_path)) {
      Trajectory gt;
      *status = ReadEurocTrajectory(gt_path, &gt);
      if (!status->ok()) return nullptr;
      if (options.gt_body_to_camera) {
        for (StampedPose& p : gt) p.world_from_cam = p.world_from_cam * calibration.body_from_cam;
      }
      AttachGroundTruth(gt, static_cast<int64_t>(options.gt_max_dt_s * 1e9), &entries);
    }
  }
  return std::make_unique<ImageListSource>(calibration.intrinsics, std::move(entries));
}

}  // namespace ccm
