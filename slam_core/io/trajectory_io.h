// Trajectory files: TUM (`t tx ty tz qx qy qz qw`, seconds), EuRoC CSV (ns, position,
// quaternion w first, extra columns ignored) and KITTI poses (12 numbers of a 3x4 [R|t] per
// line, no timestamps). Readers report the file and line of malformed input; ReadTrajectory
// picks the reader by name or by looking at the content. See docs/evaluation.md.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "slam_core/io/io_status.h"
#include "slam_core/io/trajectory.h"

namespace ccm {

enum class TrajectoryFormat { kAuto, kTum, kEuroc, kKitti };

/// "auto", "tum", "euroc", "kitti" (lower case); nullopt for anything else.
std::optional<TrajectoryFormat> ParseTrajectoryFormat(const std::string& name);
const char* ToString(TrajectoryFormat format);

/// Guesses the format from the content: a directory is a EuRoC dataset; a comma-separated first
/// data line is EuRoC; 8 whitespace-separated fields are TUM; 12 are KITTI.
IoStatus DetectTrajectoryFormat(const std::string& path, TrajectoryFormat* format);

IoStatus ReadTumTrajectory(const std::string& path, Trajectory* trajectory);
IoStatus ReadEurocTrajectory(const std::string& path, Trajectory* trajectory);
/// KITTI poses: one 3x4 row-major [R|t] per line (world_from_cam).
IoStatus ReadKittiPoses(const std::string& path, std::vector<SE3>* poses);
/// KITTI times.txt: one time in seconds per line.
IoStatus ReadKittiTimes(const std::string& path, std::vector<int64_t>* stamps_ns);

struct TrajectoryReadOptions {
  TrajectoryFormat format = TrajectoryFormat::kAuto;
  /// KITTI only: times.txt giving the stamps (first N lines are used). Empty: pose i gets
  /// stamp i seconds, so two KITTI files associate by index.
  std::string kitti_times_path;
  /// EuRoC dataset folders only: apply cam0's T_BS so the poses are camera poses.
  bool euroc_folder_camera_poses = true;
};

/// Reads any supported trajectory file, or a EuRoC dataset folder (its ground truth,
/// state_groundtruth_estimate0/data.csv, turned into cam0 poses via T_BS).
IoStatus ReadTrajectory(const std::string& path, const TrajectoryReadOptions& options,
                        Trajectory* trajectory);

/// Writers use full double precision; stamps are written exactly (seconds with 9 decimals
/// for TUM, integer ns for EuRoC). Missing parent folders are created.
IoStatus WriteTumTrajectory(const std::string& path, const Trajectory& trajectory);
IoStatus WriteEurocTrajectory(const std::string& path, const Trajectory& trajectory);
IoStatus WriteKittiPoses(const std::string& path, const Trajectory& trajectory);

}  // namespace ccm
