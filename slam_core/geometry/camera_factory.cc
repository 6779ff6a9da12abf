#include <cmath>
#include <string>

#include "slam_core/geometry/camera_models.h"

namespace ccm {

const char* CameraTypeName(CameraType type) {
  switch (type) {
    case CameraType::kPinholeRadTan: return "pinhole-radtan";
    case CameraType::kFisheyeEquidistant: return "fisheye-equidistant";
  }
  return "unknown";
}

std::string ValidateIntrinsics(const CameraIntrinsics& c) {
  if (c.width_px <= 0 || c.height_px <= 0) {
    return "image size must be positive, got " + std::to_string(c.width_px) + "x" + std::to_string(c.height_px);
  }
  if (!(c.fx > 0) || !(c.fy > 0) || !std::isfinite(c.fx) || !std::isfinite(c.fy)) return "fx and fy must be > 0";
  if (!std::isfinite(c.cx) || !std::isfinite(c.cy)) return "cx and cy must be finite";
  for (double d : c.distortion) {
    if (!std::isfinite(d)) return "distortion coefficients must be finite";
  }
  const size_t n = c.distortion.size();
  switch (c.type) {
    case CameraType::kPinholeRadTan:
      if (n != 0 && n != 4 && n != 5) {
        return "radtan needs 0, 4 (k1 k2 p1 p2) or 5 (+k3) distortion coefficients, got " + std::to_string(n);
      }
      return "";
    case CameraType::kFisheyeEquidistant:
      if (n != 4) return "equidistant needs 4 distortion coefficients (k1..k4), got " + std::to_string(n);
      return "";
  }
  return "unknown camera type";
}

std::unique_ptr<CameraModel> MakeCamera(const CameraIntrinsics& intrinsics) {
  if (!ValidateIntrinsics(intrinsics).empty()) return nullptr;
  if (intrinsics.type == CameraType::kFisheyeEquidistant) {
    return std::make_unique<FisheyeEquidistantCamera>(intrinsics);
  }
  return std::make_unique<PinholeRadTanCamera>(intrinsics);
}

}  // namespace ccm
