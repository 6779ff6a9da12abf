#include "slam_core/io/dataset.h"

#include <cmath>
#include <filesystem>

namespace ccm {
namespace fs = std::filesystem;

std::optional<DatasetFormat> ParseDatasetFormat(const std::string& name) {
  if (name == "auto") return DatasetFormat::kAuto;
  if (name == "euroc") return DatasetFormat::kEuroc;
  if (name == "tum") return DatasetFormat::kTumRgbd;
  if (name == "kitti") return DatasetFormat::kKitti;
  return std::nullopt;
}

const char* ToString(DatasetFormat format) {
  switch (format) {
    case DatasetFormat::kAuto: return "auto";
    case DatasetFormat::kEuroc: return "euroc";
    case DatasetFormat::kTumRgbd: return "tum";
    case DatasetFormat::kKitti: return "kitti";
  }
  return "?";
}

IoStatus DatasetOptions::Validate() const {
  if (path.empty()) return IoStatus::Error("dataset path is empty");
  if (!(gt_max_dt_s >= 0.0) || !std::isfinite(gt_max_dt_s)) {
    return IoStatus::Error("gt_max_dt_s must be >= 0");
  }
  if (camera.empty()) return IoStatus::Error("camera folder name is empty");
  return IoStatus::Ok();
}

IoStatus DetectDatasetFormat(const std::string& path, DatasetFormat* format) {
  if (!fs::is_directory(path)) return IoStatus::Error("dataset folder not found: " + path);
  const fs::path dir(path);
  if (fs::is_directory(dir / "mav0") || fs::exists(dir / "cam0" / "data.csv")) {
    *format = DatasetFormat::kEuroc;
  } else if (fs::exists(dir / "rgb.txt")) {
    *format = DatasetFormat::kTumRgbd;
  } else if (fs::is_directory(dir / "image_0") && fs::exists(dir / "calib.txt")) {
    *format = DatasetFormat::kKitti;
  } else {
    return IoStatus::Error(path + ": unknown dataset layout (looked for mav0/ or cam0/data.csv "
                           "(EuRoC), rgb.txt (TUM RGB-D), image_0/ + calib.txt (KITTI))");
  }
  return IoStatus::Ok();
}

std::unique_ptr<FrameSource> OpenDataset(const DatasetOptions& options, IoStatus* status) {
  *status = options.Validate();
  if (!status->ok()) return nullptr;
  DatasetFormat format = options.format;
  if (format == DatasetFormat::kAuto) {
    *status = DetectDatasetFormat(options.path, &format);
    if (!status->ok()) return nullptr;
  } else if (!fs::is_directory(options.path)) {
    *status = IoStatus::Error("dataset folder not found: " + options.path);
    return nullptr;
  }
  switch (format) {
    case DatasetFormat::kEuroc: return OpenEurocDataset(options, status);
    case DatasetFormat::kTumRgbd: return OpenTumRgbdDataset(options, status);
    case DatasetFormat::kKitti: return OpenKittiDataset(options, status);
    case DatasetFormat::kAuto: break;
  }
  *status = IoStatus::Error("unreachable dataset format");
  return nullptr;
}

std::unique_ptr<FrameSource> OpenDataset(const std::string& path, DatasetFormat format,
                                         IoStatus* status) {
  DatasetOptions options;
  options.path = path;
  options.format = format;
  return OpenDataset(options, status);
}

}  // namespace ccm
