// Ray-casting renderer for a World seen through any ccm::CameraModel.
// Why ray casting: lens distortion (radtan, fisheye) is exact per pixel, occlusion is
// exact, and the same ray gives ground-truth depth and surface ids for tests.
// How: per-pixel unit bearings are computed once per camera with Unproject; per frame,
// back-facing surfaces are culled and each 16x16 tile gets the surfaces whose bounding
// spheres touch the tile's bearing cone. Textures are sampled trilinearly from mipmaps.
// All methods are const and thread-safe.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"
#include "tests/sim/world.h"

namespace ccm::sim {

struct RenderOptions {
  double read_noise_dn = 1.5;     ///< Gaussian sensor noise std [grey levels]; 0 disables noise
  double shot_noise_gain = 0.04;  ///< photon noise variance per grey level [DN]
  double vignetting = 0.15;       ///< brightness loss at the image corner (0 = none)
  double lod_bias = 0.0;          ///< added to the mip level (> 0 blurs, < 0 sharpens/aliases)
  double anisotropy = 0.5;        ///< 0: mip level from the short footprint axis, 1: from the long one
  int motion_blur_samples = 1;    ///< sub-frames averaged over the exposure (1 = no blur)
  double exposure_time_s = 0.008; ///< shutter time, used for motion blur
  int tile_px = 16;               ///< culling tile size [pixels]
  std::string Validate() const;   ///< empty if valid, else the problem
};

/// Where a camera ray meets the world.
struct RayHit {
  Eigen::Vector3d point_w;   ///< hit point in the world frame [m]
  double range_m = 0.0;      ///< distance from the camera centre along the ray
  double depth_m = 0.0;      ///< z of the hit point in the camera frame
  int surface = -1;          ///< index into World::surfaces()
  Eigen::Vector2d surface_uv_m = Eigen::Vector2d::Zero();  ///< position on the surface
};

struct PackedSurface;  // renderer.cc: a surface prepared for one frame

class Renderer {
 public:
  /// nullptr + *error set if the camera or options are invalid.
  static std::unique_ptr<Renderer> Create(std::shared_ptr<const World> world, const CameraIntrinsics& camera,
                                          const RenderOptions& options, std::string* error);

  /// Noise-free image irradiance (CV_32F, grey levels, before exposure gain and noise).
  cv::Mat RenderRadiance(const SE3& world_from_cam) const;
  /// Final 8-bit image: mean radiance over `poses` (motion blur; one pose = sharp) times
  /// `gain`, plus sensor noise drawn from `noise_key` (same key => same noise).
  cv::Mat Render(const std::vector<SE3>& poses, float gain, std::uint64_t noise_key) const;
  cv::Mat Render(const SE3& world_from_cam, float gain, std::uint64_t noise_key) const {
    return Render(std::vector<SE3>{world_from_cam}, gain, noise_key);
  }

  /// Exact ray cast through a (sub-)pixel position; nullopt if the pixel has no valid
  /// bearing or the ray hits nothing.
  std::optional<RayHit> CastRay(const SE3& world_from_cam, const Eigen::Vector2d& uv) const;
  /// CastRay for many pixels of one pose (the per-frame culling done once).
  std::vector<std::optional<RayHit>> CastRays(const SE3& world_from_cam, const std::vector<Eigen::Vector2d>& uvs) const;
  /// Per-pixel z-depth [m] (CV_32F, 0 = no hit) and surface index (CV_32S, -1 = no hit).
  void RenderDepth(const SE3& world_from_cam, cv::Mat* depth_m, cv::Mat* surface) const;

  const CameraModel& camera() const { return *camera_; }
  const World& world() const { return *world_; }
  const RenderOptions& options() const { return options_; }

 private:
  struct Hit {
    double t = 0.0;
    int surface = -1;
    double a = 0.0, b = 0.0;   // surface coordinates [m]
    double cos_incidence = 1.0;
  };
  struct FrameSetup;
  Renderer(std::shared_ptr<const World> world, std::unique_ptr<CameraModel> camera, const RenderOptions& options);
  void PrecomputeRays();
  FrameSetup Setup(const SE3& world_from_cam, bool with_tiles) const;
  static bool Trace(const PackedSurface* cand, int n_cand, const Eigen::Vector3d& d_w, Hit* hit);
  // Calls fn(pixel_index, hit_or_null) for every pixel, tile by tile.
  template <typename Fn>
  void ForEachPixel(const SE3& world_from_cam, Fn&& fn) const;

  std::shared_ptr<const World> world_;
  std::unique_ptr<CameraModel> camera_;
  RenderOptions options_;
  int width_ = 0, height_ = 0, tiles_x_ = 0, tiles_y_ = 0;
  std::vector<Eigen::Vector3d> bearing_;   // per pixel, camera frame, unit
  std::vector<unsigned char> valid_;       // per pixel: bearing exists
  std::vector<float> pixel_angle_;         // per pixel angular size [rad]
  std::vector<float> vignette_;            // per pixel brightness factor
  std::vector<Eigen::Vector3d> tile_axis_; // per tile cone axis (camera frame)
  std::vector<double> tile_half_angle_;    // per tile cone half angle [rad]
};

}  // namespace ccm::sim
