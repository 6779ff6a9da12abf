// Camera calibration files read with yaml-cpp: EuRoC/Kalibr `sensor.yaml` (intrinsics,
// distortion, resolution, T_BS) and a small calibration file for datasets without one (TUM).
#pragma once

#include <string>

#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"
#include "slam_core/io/io_status.h"

namespace ccm {

struct EurocCameraCalibration {
  CameraIntrinsics intrinsics;
  SE3 body_from_cam;   ///< T_BS: camera (sensor) frame to body frame
  double rate_hz = 0;  ///< 0 if absent
};

/// EuRoC sensor.yaml: camera_model (pinhole), intrinsics [fu fv cu cv], resolution [w h],
/// distortion_model (radial-tangential | radtan | equidistant), distortion_coefficients,
/// T_BS {rows: 4, cols: 4, data: [16 numbers, row-major]} (identity if absent), rate_hz.
IoStatus ReadEurocSensorYaml(const std::string& path, EurocCameraCalibration* calibration);

/// Calibration for a dataset without one. Accepts the EuRoC sensor.yaml keys above, or flat keys
///   width, height, fx, fy, cx, cy, [distortion: [k1 k2 p1 p2 (k3)], distortion_model]
/// optionally prefixed "Camera." (ORB-SLAM settings files: Camera.fx, Camera.k1, ...).
IoStatus ReadCalibrationYaml(const std::string& path, CameraIntrinsics* intrinsics);

/// Checks sizes and values of a calibration (positive focal lengths and image size, 4-5
/// radtan or 4 equidistant coefficients). `what` names the source in the message.
IoStatus ValidateIntrinsics(const CameraIntrinsics& intrinsics, const std::string& what);

}  // namespace ccm
