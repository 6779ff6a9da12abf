// Published calibrations used as defaults by the simulator and as realistic cameras in
// tests: one definition instead of a copy per test file.
#pragma once

#include "slam_core/geometry/camera.h"

namespace ccm {

/// EuRoC MAV cam0 (MT9V034, 752x480, radial-tangential).
inline CameraIntrinsics EurocCam0Intrinsics() {
  CameraIntrinsics c;
  c.type = CameraType::kPinholeRadTan;
  c.width_px = 752;
  c.height_px = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return c;
}

/// TUM-VI cam0 (512x512, equidistant fisheye).
inline CameraIntrinsics TumViFisheyeIntrinsics() {
  CameraIntrinsics c;
  c.type = CameraType::kFisheyeEquidistant;
  c.width_px = 512;
  c.height_px = 512;
  c.fx = 190.978;
  c.fy = 190.973;
  c.cx = 254.932;
  c.cy = 256.897;
  c.distortion = {0.0034823894, 0.000715034, -0.0020532361, 0.00020293673};
  return c;
}

}  // namespace ccm
