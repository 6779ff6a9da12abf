// sensor_msgs/Image and sensor_msgs/CameraInfo (as ROS 2's DDS layer names them,
// idl/ros2/ros2_msgs.idl) -> what the VO takes: an 8-bit gray image and a CameraIntrinsics.
// Pure functions, no DDS: the thin conversion layer of ccm_agent --ros2-image
// (ros2_camera_source.h). Every refusal says what was received and what would be accepted.
#pragma once

#include <opencv2/core.hpp>

#include <cstdint>
#include <string>

#include "idl/ros2/ros2_msgs.h"
#include "slam_core/geometry/camera.h"

namespace ccm::agent {

/// The encodings accepted (REP 2001 / sensor_msgs/image_encodings.hpp names).
inline constexpr const char* kRos2ImageEncodings = "mono8, 8UC1, bgr8, rgb8, bgra8, rgba8";

/// builtin_interfaces/Time -> nanoseconds.
int64_t Ros2StampNs(const builtin_interfaces::msg::dds_::Time_& stamp);

/// The image as 8-bit gray (always a copy: the message's buffer is not kept). False and a
/// message for an encoding not in kRos2ImageEncodings, a zero or huge size, a step shorter
/// than a row or data shorter than step x height.
bool Ros2ImageToGray(const sensor_msgs::msg::dds_::Image_& image, cv::Mat* gray, std::string* error);

/// The calibration of the images the camera publishes: K and D of CameraInfo, with binning
/// and region of interest applied as REP 104 defines them (K is for the full, unbinned
/// sensor; the image is the ROI divided by the binning). Distortion models: plumb_bob and
/// rational_polynomial whose k4..k6 are 0 (radial-tangential), equidistant (fisheye), or
/// none ("" with no coefficients). False and a message otherwise (zero K, unknown model,
/// wrong number of coefficients).
bool Ros2CameraInfoToIntrinsics(const sensor_msgs::msg::dds_::CameraInfo_& info, CameraIntrinsics* intrinsics,
                                std::string* error);

}  // namespace ccm::agent
