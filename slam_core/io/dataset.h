// Dataset readers: EuRoC ASL, TUM RGB-D and KITTI odometry folders opened as a FrameSource,
// with ground truth attached to the frames. One factory, OpenDataset, picks the reader from
// DatasetOptions::format or detects it from the folder layout. Playback rate is the caller's.
//
//   DatasetOptions options;
//   options.path = dir;
//   IoStatus status;
//   std::unique_ptr<FrameSource> source = OpenDataset(options, &status);
//   if (!source) fail(status.message());
//   while (auto frame = source->Next()) { ... }
//   if (!source->error().empty()) fail(source->error());
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "slam_core/io/image_list_source.h"
#include "slam_core/io/io_status.h"

namespace ccm {

enum class DatasetFormat { kAuto, kEuroc, kTumRgbd, kKitti };

/// "auto", "euroc", "tum", "kitti"; nullopt otherwise.
std::optional<DatasetFormat> ParseDatasetFormat(const std::string& name);
const char* ToString(DatasetFormat format);

struct DatasetOptions {
  std::string path;                             ///< dataset folder (EuRoC: the one with mav0/ or mav0 itself)
  DatasetFormat format = DatasetFormat::kAuto;  ///< kAuto: detected from the layout
  std::string camera = "cam0";                  ///< EuRoC camera folder
  /// TUM: calibration YAML (see ReadCalibrationYaml). Empty: fr1/fr2/fr3 defaults chosen from the
  /// folder name (e.g. rgbd_dataset_freiburg1_xyz). Other formats: overrides their calibration.
  std::string calibration_path;
  /// Ground-truth file override. KITTI: the poses file; empty = <path>/poses.txt, or
  /// <path>/../../poses/<sequence>.txt (standard layout), or none if neither exists.
  std::string ground_truth_path;
  bool load_ground_truth = true;
  double gt_max_dt_s = 0.01;  ///< [s] frame <-> ground truth nearest-stamp tolerance
  /// EuRoC: ground truth is the body pose; apply T_BS of the camera so frames get camera poses.
  bool gt_body_to_camera = true;

  IoStatus Validate() const;
};

/// Opens a dataset; on failure returns nullptr and a message naming the file (and line).
std::unique_ptr<FrameSource> OpenDataset(const DatasetOptions& options, IoStatus* status);
/// Same with default options for everything but the folder and the format.
std::unique_ptr<FrameSource> OpenDataset(const std::string& path, DatasetFormat format,
                                         IoStatus* status);
/// Detects the layout: mav0/ or cam0/data.csv -> EuRoC, rgb.txt -> TUM, image_0/ + calib.txt
/// -> KITTI.
IoStatus DetectDatasetFormat(const std::string& path, DatasetFormat* format);

/// Per-format openers (OpenDataset calls these); the concrete type exposes the index.
std::unique_ptr<ImageListSource> OpenEurocDataset(const DatasetOptions& options, IoStatus* status);
std::unique_ptr<ImageListSource> OpenTumRgbdDataset(const DatasetOptions& options, IoStatus* status);
std::unique_ptr<ImageListSource> OpenKittiDataset(const DatasetOptions& options, IoStatus* status);

/// The mav0 folder of a EuRoC dataset given either its parent or itself.
std::optional<std::string> EurocMavFolder(const std::string& path);
/// Published calibration of the TUM RGB-D Kinects (freiburg 1, 2, 3), 640x480; nullopt for
/// other numbers.
std::optional<CameraIntrinsics> TumDefaultIntrinsics(int freiburg);

}  // namespace ccm
