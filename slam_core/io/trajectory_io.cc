#include "slam_core/io/trajectory_io.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>

#include "slam_core/io/dataset.h"
#include "slam_core/io/calibration_yaml.h"
#include "slam_core/io/text_table.h"

namespace ccm {
namespace {

using io_internal::ParseDoubles;
using io_internal::TextLine;
using io_internal::Where;

// Rejects quaternions that are far from unit norm: usually a column-order mistake.
IoStatus MakeQuaternion(const std::string& path, int line, double w, double x, double y, double z,
                        Eigen::Quaterniond* q) {
  const double norm = std::sqrt(w * w + x * x + y * y + z * z);
  if (std::fabs(norm - 1.0) > 1e-2) {
    return IoStatus::Error(Where(path, line) + ": quaternion norm is " + std::to_string(norm) +
                           ", expected 1 (wrong column order?)");
  }
  *q = Eigen::Quaterniond(w, x, y, z).normalized();
  return IoStatus::Ok();
}

std::string FormatSeconds(int64_t stamp_ns) {
  const bool negative = stamp_ns < 0;
  const uint64_t abs_ns = negative ? static_cast<uint64_t>(-(stamp_ns + 1)) + 1
                                   : static_cast<uint64_t>(stamp_ns);
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(abs_ns / 1000000000ULL),
                static_cast<unsigned long long>(abs_ns % 1000000000ULL));
  return buffer;
}

IoStatus OpenForWriting(const std::string& path, std::ofstream* out) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  out->open(path);
  if (!*out) return IoStatus::Error("cannot open " + path + " for writing");
  *out << std::setprecision(std::numeric_limits<double>::max_digits10);
  return IoStatus::Ok();
}

IoStatus FinishWriting(const std::string& path, std::ofstream* out) {
  out->close();
  if (out->fail()) return IoStatus::Error("error while writing " + path);
  return IoStatus::Ok();
}

IoStatus ReadEurocFolderTrajectory(const std::string& path, bool camera_poses,
                                   Trajectory* trajectory) {
  const std::optional<std::string> mav = EurocMavFolder(path);
  if (!mav) return IoStatus::Error(path + " is a directory but not a EuRoC dataset (no mav0/)");
  const std::string gt_path = *mav + "/state_groundtruth_estimate0/data.csv";
  IoStatus status = ReadEurocTrajectory(gt_path, trajectory);
  if (!status.ok() || !camera_poses) return status;
  const std::string sensor = *mav + "/cam0/sensor.yaml";
  if (!std::filesystem::exists(sensor)) return IoStatus::Ok();  // no camera: body poses
  EurocCameraCalibration calibration;
  status = ReadEurocSensorYaml(sensor, &calibration);
  if (!status.ok()) return status;
  for (StampedPose& pose : *trajectory) {
    pose.world_from_cam = pose.world_from_cam * calibration.body_from_cam;
  }
  return IoStatus::Ok();
}

}  // namespace

std::optional<TrajectoryFormat> ParseTrajectoryFormat(const std::string& name) {
  if (name == "auto") return TrajectoryFormat::kAuto;
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "euroc") return TrajectoryFormat::kEuroc;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  return std::nullopt;
}

const char* ToString(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kAuto: return "auto";
    case TrajectoryFormat::kTum: return "tum";
    case TrajectoryFormat::kEuroc: return "euroc";
    case TrajectoryFormat::kKitti: return "kitti";
  }
  return "?";
}

IoStatus DetectTrajectoryFormat(const std::string& path, TrajectoryFormat* format) {
  if (std::filesystem::is_directory(path)) {
    *format = TrajectoryFormat::kEuroc;
    return IoStatus::Ok();
  }
  std::ifstream in(path);
  if (!in) return IoStatus::Error("cannot open " + path);
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const size_t first = text.find_first_not_of(" \t\r");
    if (first == std::string::npos || text[first] == '#') continue;
    if (text.find(',') != std::string::npos) {
      *format = TrajectoryFormat::kEuroc;
      return IoStatus::Ok();
    }
    std::istringstream fields(text);
    int count = 0;
    for (std::string f; fields >> f;) ++count;
    if (count == 8) *format = TrajectoryFormat::kTum;
    else if (count == 12) *format = TrajectoryFormat::kKitti;
    else {
      return IoStatus::Error(Where(path, number) + ": cannot detect the trajectory format: " +
                             std::to_string(count) +
                             " fields (TUM has 8, KITTI 12, EuRoC is comma-separated)");
    }
    return IoStatus::Ok();
  }
  return IoStatus::Error(path + " has no data lines");
}

IoStatus ReadTumTrajectory(const std::string& path, Trajectory* trajectory) {
  trajectory->clear();
  std::vector<TextLine> lines;
  IoStatus status = io_internal::ReadTable(path, &lines);
  if (!status.ok()) return status;
  for (const TextLine& line : lines) {
    if (line.fields.size() != 8) {
      return IoStatus::Error(Where(path, line.number) + ": expected 8 fields 't tx ty tz qx qy qz qw'"
                             ", found " + std::to_string(line.fields.size()));
    }
    StampedPose pose;
    if (!io_internal::ParseSecondsToNs(line.fields[0], &pose.stamp_ns)) {
      return IoStatus::Error(Where(path, line.number) + ": bad timestamp '" + line.fields[0] + "'");
    }
    double v[7];
    if (!(status = ParseDoubles(path, line, 1, 7, v)).ok()) return status;
    Eigen::Quaterniond q;
    if (!(status = MakeQuaternion(path, line.number, v[6], v[3], v[4], v[5], &q)).ok()) return status;
    pose.world_from_cam = SE3(q, Eigen::Vector3d(v[0], v[1], v[2]));
    trajectory->push_back(pose);
  }
  return IoStatus::Ok();
}

IoStatus ReadEurocTrajectory(const std::string& path, Trajectory* trajectory) {
  trajectory->clear();
  std::vector<TextLine> lines;
  IoStatus status = io_internal::ReadTable(path, &lines);
  if (!status.ok()) return status;
  for (const TextLine& line : lines) {
    if (line.fields.size() < 8) {
      return IoStatus::Error(Where(path, line.number) +
                             ": expected >= 8 fields 'ns,px,py,pz,qw,qx,qy,qz', found " +
                             std::to_string(line.fields.size()));
    }
    StampedPose pose;
    if (!io_internal::ParseInt64(line.fields[0], &pose.stamp_ns)) {
      return IoStatus::Error(Where(path, line.number) + ": timestamp '" + line.fields[0] +
                             "' is not an integer number of nanoseconds");
    }
    double v[7];
    if (!(status = ParseDoubles(path, line, 1, 7, v)).ok()) return status;
    Eigen::Quaterniond q;
    if (!(status = MakeQuaternion(path, line.number, v[3], v[4], v[5], v[6], &q)).ok()) return status;
    pose.world_from_cam = SE3(q, Eigen::Vector3d(v[0], v[1], v[2]));
    trajectory->push_back(pose);
  }
  return IoStatus::Ok();
}

IoStatus ReadKittiPoses(const std::string& path, std::vector<SE3>* poses) {
  poses->clear();
  std::vector<TextLine> lines;
  IoStatus status = io_internal::ReadTable(path, &lines);
  if (!status.ok()) return status;
  for (const TextLine& line : lines) {
    if (line.fields.size() != 12) {
      return IoStatus::Error(Where(path, line.number) + ": expected 12 numbers (3x4 [R|t]), found " +
                             std::to_string(line.fields.size()));
    }
    double v[12];
    if (!(status = ParseDoubles(path, line, 0, 12, v)).ok()) return status;
    Eigen::Matrix3d R;
    R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    const double ortho_error = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
    if (ortho_error > 1e-3 || R.determinant() < 0.0) {
      return IoStatus::Error(Where(path, line.number) + ": rotation is not orthonormal (error " +
                             std::to_string(ortho_error) + ")");
    }
    poses->emplace_back(R, Eigen::Vector3d(v[3], v[7], v[11]));
  }
  return IoStatus::Ok();
}

IoStatus ReadKittiTimes(const std::string& path, std::vector<int64_t>* stamps_ns) {
  stamps_ns->clear();
  std::vector<TextLine> lines;
  IoStatus status = io_internal::ReadTable(path, &lines);
  if (!status.ok()) return status;
  for (const TextLine& line : lines) {
    int64_t stamp = 0;
    if (line.fields.size() != 1 || !io_internal::ParseSecondsToNs(line.fields[0], &stamp)) {
      return IoStatus::Error(Where(path, line.number) + ": expected one time in seconds");
    }
    stamps_ns->push_back(stamp);
  }
  return IoStatus::Ok();
}

IoStatus ReadTrajectory(const std::string& path, const TrajectoryReadOptions& options,
                        Trajectory* trajectory) {
  trajectory->clear();
  if (!std::filesystem::exists(path)) return IoStatus::Error("no such file: " + path);
  TrajectoryFormat format = options.format;
  IoStatus status;
  if (format == TrajectoryFormat::kAuto && !(status = DetectTrajectoryFormat(path, &format)).ok()) {
    return status;
  }
  if (std::filesystem::is_directory(path)) {
    if (format != TrajectoryFormat::kEuroc) {
      return IoStatus::Error(path + " is a directory; only EuRoC dataset folders are read");
    }
    return ReadEurocFolderTrajectory(path, options.euroc_folder_camera_poses, trajectory);
  }
  if (format == TrajectoryFormat::kTum) return ReadTumTrajectory(path, trajectory);
  if (format == TrajectoryFormat::kEuroc) return ReadEurocTrajectory(path, trajectory);
  std::vector<SE3> poses;
  if (!(status = ReadKittiPoses(path, &poses)).ok()) return status;
  std::vector<int64_t> stamps;
  if (!options.kitti_times_path.empty()) {
    if (!(status = ReadKittiTimes(options.kitti_times_path, &stamps)).ok()) return status;
    if (stamps.size() < poses.size()) {
      return IoStatus::Error(options.kitti_times_path + " has " + std::to_string(stamps.size()) +
                             " times but " + path + " has " + std::to_string(poses.size()) +
                             " poses");
    }
  }
  for (size_t i = 0; i < poses.size(); ++i) {
    const int64_t stamp = stamps.empty() ? static_cast<int64_t>(i) * 1000000000LL : stamps[i];
    trajectory->push_back(StampedPose{stamp, poses[i]});
  }
  return IoStatus::Ok();
}

IoStatus WriteTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out;
  IoStatus status = OpenForWriting(path, &out);
  if (!status.ok()) return status;
  out << "# timestamp[s] tx ty tz qx qy qz qw (world_from_cam)\n";
  for (const StampedPose& p : trajectory) {
    const Eigen::Vector3d& t = p.world_from_cam.translation();
    const Eigen::Quaterniond& q = p.world_from_cam.rotation();
    out << FormatSeconds(p.stamp_ns) << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' '
        << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  return FinishWriting(path, &out);
}

IoStatus WriteEurocTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out;
  IoStatus status = OpenForWriting(path, &out);
  if (!status.ok()) return status;
  out << "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
         "q_RS_y [], q_RS_z []\n";
  for (const StampedPose& p : trajectory) {
    const Eigen::Vector3d& t = p.world_from_cam.translation();
    const Eigen::Quaterniond& q = p.world_from_cam.rotation();
    out << p.stamp_ns << ',' << t.x() << ',' << t.y() << ',' << t.z() << ',' << q.w() << ','
        << q.x() << ',' << q.y() << ',' << q.z() << '\n';
  }
  return FinishWriting(path, &out);
}

IoStatus WriteKittiPoses(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out;
  IoStatus status = OpenForWriting(path, &out);
  if (!status.ok()) return status;
  for (const StampedPose& p : trajectory) {
    const Eigen::Matrix3d R = p.world_from_cam.rotation_matrix();
    const Eigen::Vector3d& t = p.world_from_cam.translation();
    for (int r = 0; r < 3; ++r) {
      out << R(r, 0) << ' ' << R(r, 1) << ' ' << R(r, 2) << ' ' << t(r) << (r < 2 ? ' ' : '\n');
    }
  }
  return FinishWriting(path, &out);
}

}  // namespace ccm
