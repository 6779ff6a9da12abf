// Camera model interface shared by all modules. Each agent may have its own camera,
// so algorithms take a `const CameraModel&` instead of assuming one global calibration.
// Frames: camera frame z forward, x right, y down; pixel (0,0) is the centre of the
// top-left pixel.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace ccm {

enum class CameraType { kPinholeRadTan = 0, kFisheyeEquidistant = 1 };

/// Plain calibration record: what travels in messages and config files.
struct CameraIntrinsics {
  CameraType type = CameraType::kPinholeRadTan;
  int width_px = 0;
  int height_px = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  /// radtan: k1 k2 p1 p2 [k3]; equidistant: k1 k2 k3 k4.
  std::vector<double> distortion;
};

class CameraModel {
 public:
  virtual ~CameraModel() = default;
  virtual CameraType type() const = 0;
  virtual const CameraIntrinsics& intrinsics() const = 0;
  int width() const { return intrinsics().width_px; }
  int height() const { return intrinsics().height_px; }

  /// Projects a point in the camera frame to distorted pixels. False if behind the
  /// camera or outside the model's valid domain (image bounds are NOT checked here).
  virtual bool Project(const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv,
                       Eigen::Matrix<double, 2, 3>* d_uv_d_p = nullptr) const = 0;
  /// Project for cost functions: the same pixel and Jacobian wherever Project succeeds, and the
  /// distortion model continued smoothly past the fold where Project says "not visible" (false
  /// only where no pixel can be computed, e.g. behind a pinhole). Why: a keypoint near the edge
  /// of a strongly distorted image belongs to a point close to the fold, and a failed evaluation
  /// makes Ceres reject the whole step: one such observation froze every step of a global BA
  /// (wide-camera scenes, 2026-12-06). Its measurement keeps the point on the right side.
  virtual bool ProjectForCost(const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv,
                              Eigen::Matrix<double, 2, 3>* d_uv_d_p = nullptr) const {
    return Project(p_cam, uv, d_uv_d_p);
  }
  /// Unit bearing vector for a distorted pixel. False if the pixel cannot be undistorted.
  virtual bool Unproject(const Eigen::Vector2d& uv, Eigen::Vector3d* bearing) const = 0;
  /// Undistorted normalized image-plane coordinates (x/z, y/z) of a pixel. False if the
  /// pixel cannot be undistorted or its ray points backwards (fisheye beyond 90 deg).
  bool UnprojectToNormalized(const Eigen::Vector2d& uv, Eigen::Vector2d* xy) const {
    Eigen::Vector3d b;
    if (!Unproject(uv, &b) || b.z() <= 1e-9) return false;
    *xy = b.head<2>() / b.z();
    return true;
  }
  bool InImage(const Eigen::Vector2d& uv, double border_px = 0.0) const {
    return uv.x() >= border_px && uv.y() >= border_px && uv.x() <= width() - 1 - border_px &&
           uv.y() <= height() - 1 - border_px;
  }
};

/// Empty string if the calibration is usable, otherwise what is wrong with it
/// (e.g. "fx must be > 0", "equidistant needs 4 distortion coefficients, got 5").
std::string ValidateIntrinsics(const CameraIntrinsics& intrinsics);

/// Builds the concrete model for a calibration; nullptr if ValidateIntrinsics fails.
std::unique_ptr<CameraModel> MakeCamera(const CameraIntrinsics& intrinsics);

/// Name used in files and messages: "pinhole-radtan" / "fisheye-equidistant".
const char* CameraTypeName(CameraType type);

}  // namespace ccm
