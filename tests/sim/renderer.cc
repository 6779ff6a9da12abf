#include "tests/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <opencv2/core.hpp>

#include "tests/sim/sim_random.h"

namespace ccm::sim {

std::string RenderOptions::Validate() const {
  if (!(read_noise_dn >= 0.0 && read_noise_dn < 50.0)) return "read_noise_dn must be in [0, 50)";
  if (!(shot_noise_gain >= 0.0 && shot_noise_gain < 10.0)) return "shot_noise_gain must be in [0, 10)";
  if (!(vignetting >= 0.0 && vignetting < 1.0)) return "vignetting must be in [0, 1)";
  if (!(std::abs(lod_bias) <= 4.0)) return "lod_bias must be in [-4, 4]";
  if (!(anisotropy >= 0.0 && anisotropy <= 1.0)) return "anisotropy must be in [0, 1]";
  if (motion_blur_samples < 1 || motion_blur_samples > 32) return "motion_blur_samples must be in [1, 32]";
  if (!(exposure_time_s >= 0.0 && exposure_time_s < 1.0)) return "exposure_time_s must be in [0, 1) s";
  if (tile_px < 4 || tile_px > 128) return "tile_px must be in [4, 128]";
  return {};
}

// One surface as seen from this frame's camera centre, packed for the inner loop.
struct PackedSurface {
  Eigen::Vector3d n, o_rel, u, v;  // normal, origin relative to the camera, axes
  double n_dot_o;                  // n . o_rel (< 0 for surfaces facing the camera)
  double su, sv;                   // extents [m]
  int index;                       // into World::surfaces()
};

// Per-frame data in the world frame, relative to the camera centre.
struct Renderer::FrameSetup {
  Eigen::Matrix3d R;                 // world_from_cam rotation
  Eigen::Vector3d center;            // camera centre in the world
  std::vector<PackedSurface> visible;  // surfaces facing the camera
  std::vector<int> tile_begin;       // candidates of tile k: cand[tile_begin[k] .. tile_begin[k+1])
  std::vector<PackedSurface> cand;   // copies, so that each tile's list is contiguous
};

namespace {

// log2 to about 0.01 for the mip level: exponent + quadratic in the mantissa.
inline float FastLog2(float x) {
  std::uint32_t bits;
  std::memcpy(&bits, &x, sizeof(bits));
  const float e = static_cast<float>(static_cast<int>((bits >> 23) & 255u) - 127);
  bits = (bits & 0x007FFFFFu) | 0x3F800000u;
  float m;
  std::memcpy(&m, &bits, sizeof(m));
  return e + (-0.34484843f * m + 2.02466578f) * m - 1.67487759f;
}

}  // namespace

std::unique_ptr<Renderer> Renderer::Create(std::shared_ptr<const World> world, const CameraIntrinsics& camera,
                                           const RenderOptions& options, std::string* error) {
  std::string e = options.Validate();
  if (e.empty() && !world) e = "no world";
  if (!e.empty()) {
    if (error) *error = "render options: " + e;
    return nullptr;
  }
  const std::string cam_error = ValidateIntrinsics(camera);
  std::unique_ptr<CameraModel> model = cam_error.empty() ? MakeCamera(camera) : nullptr;
  if (!model) {
    if (error) *error = "camera: " + (cam_error.empty() ? std::string("unsupported model") : cam_error);
    return nullptr;
  }
  return std::unique_ptr<Renderer>(new Renderer(std::move(world), std::move(model), options));
}

Renderer::Renderer(std::shared_ptr<const World> world, std::unique_ptr<CameraModel> camera,
                   const RenderOptions& options)
    : world_(std::move(world)), camera_(std::move(camera)), options_(options) {
  width_ = camera_->width();
  height_ = camera_->height();
  tiles_x_ = (width_ + options_.tile_px - 1) / options_.tile_px;
  tiles_y_ = (height_ + options_.tile_px - 1) / options_.tile_px;
  PrecomputeRays();
}

void Renderer::PrecomputeRays() {
  const size_t n = static_cast<size_t>(width_) * height_;
  bearing_.assign(n, Eigen::Vector3d::UnitZ());
  valid_.assign(n, 0);
  pixel_angle_.assign(n, 0.0f);
  vignette_.assign(n, 1.0f);
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x) {
      Eigen::Vector3d b;
      const size_t i = static_cast<size_t>(y) * width_ + x;
      if (camera_->Unproject(Eigen::Vector2d(x, y), &b) && std::isfinite(b.norm())) {
        bearing_[i] = b.normalized();
        valid_[i] = 1;
      }
    }
  const double half_diag2 = 0.25 * (double(width_) * width_ + double(height_) * height_);
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x) {
      const size_t i = static_cast<size_t>(y) * width_ + x;
      const size_t ix = x + 1 < width_ ? i + 1 : i - 1;
      const size_t iy = y + 1 < height_ ? i + width_ : i - width_;
      const double ax = std::acos(std::clamp(bearing_[i].dot(bearing_[ix]), -1.0, 1.0));
      const double ay = std::acos(std::clamp(bearing_[i].dot(bearing_[iy]), -1.0, 1.0));
      pixel_angle_[i] = static_cast<float>(std::sqrt(std::max(ax * ay, 1e-12)));
      const double dx = x - 0.5 * (width_ - 1), dy = y - 0.5 * (height_ - 1);
      vignette_[i] = static_cast<float>(1.0 - options_.vignetting * (dx * dx + dy * dy) / half_diag2);
    }
  const int T = options_.tile_px;
  tile_axis_.assign(static_cast<size_t>(tiles_x_) * tiles_y_, Eigen::Vector3d::UnitZ());
  tile_half_angle_.assign(tile_axis_.size(), -1.0);  // < 0: no valid pixel in the tile
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      const int x1 = std::min(width_, (tx + 1) * T), y1 = std::min(height_, (ty + 1) * T);
      for (int y = ty * T; y < y1; ++y)
        for (int x = tx * T; x < x1; ++x)
          if (valid_[y * width_ + x]) sum += bearing_[y * width_ + x];
      if (sum.norm() < 1e-9) continue;
      const Eigen::Vector3d axis = sum.normalized();
      double half = 0.0;
      for (int y = ty * T; y < y1; ++y)
        for (int x = tx * T; x < x1; ++x)
          if (valid_[y * width_ + x])
            half = std::max(half, std::acos(std::clamp(axis.dot(bearing_[y * width_ + x]), -1.0, 1.0)));
      const size_t k = static_cast<size_t>(ty) * tiles_x_ + tx;
      tile_axis_[k] = axis;
      tile_half_angle_[k] = half + 1e-4;
    }
}

Renderer::FrameSetup Renderer::Setup(const SE3& world_from_cam, bool with_tiles) const {
  FrameSetup f;
  f.R = world_from_cam.rotation_matrix();
  f.center = world_from_cam.translation();
  const auto& surfaces = world_->surfaces();
  std::vector<Eigen::Vector3d> sphere_c;
  std::vector<double> sphere_r;
  for (size_t s = 0; s < surfaces.size(); ++s) {
    const Surface& S = surfaces[s];
    PackedSurface p;
    p.o_rel = S.origin - f.center;
    p.n = S.normal();
    p.u = S.axis_u;
    p.v = S.axis_v;
    p.su = S.size_u_m;
    p.sv = S.size_v_m;
    p.n_dot_o = p.n.dot(p.o_rel);
    p.index = static_cast<int>(s);
    if (p.n_dot_o < -1e-12) {
      f.visible.push_back(p);
      sphere_c.push_back(S.center() - f.center);
      sphere_r.push_back(0.5 * std::hypot(S.size_u_m, S.size_v_m));
    }
  }
  if (!with_tiles) return f;
  // Tile culling: keep a surface for a tile if some ray of the tile's cone approaches its
  // front side (n . d < 0 for some d, i.e. n . axis < sin(half angle)) and its bounding
  // sphere meets the cone.
  f.tile_begin.assign(tile_axis_.size() + 1, 0);
  for (size_t k = 0; k < tile_axis_.size(); ++k) {
    f.tile_begin[k] = static_cast<int>(f.cand.size());
    if (tile_half_angle_[k] < 0.0) continue;
    const Eigen::Vector3d axis = f.R * tile_axis_[k];
    const double sin_half = std::sin(tile_half_angle_[k]) + 1e-6;
    for (size_t j = 0; j < f.visible.size(); ++j) {
      if (f.visible[j].n.dot(axis) >= sin_half) continue;
      const double dist = sphere_c[j].norm();
      bool keep = dist <= sphere_r[j];
      if (!keep) {
        const double ang = std::acos(std::clamp(axis.dot(sphere_c[j]) / dist, -1.0, 1.0));
        keep = ang <= tile_half_angle_[k] + std::asin(sphere_r[j] / dist);
      }
      if (keep) f.cand.push_back(f.visible[j]);
    }
  }
  f.tile_begin.back() = static_cast<int>(f.cand.size());
  return f;
}

bool Renderer::Trace(const PackedSurface* cand, int n_cand, const Eigen::Vector3d& d, Hit* hit) {
  double best = std::numeric_limits<double>::infinity();
  for (int c = 0; c < n_cand; ++c) {
    const PackedSurface& s = cand[c];
    const double denom = s.n.dot(d);
    if (denom >= -1e-12) continue;  // ray parallel to or leaving the front side
    const double t = s.n_dot_o / denom;
    if (!(t > 0.0) || t >= best) continue;
    const Eigen::Vector3d p = t * d - s.o_rel;
    const double a = p.dot(s.u);
    const double b = p.dot(s.v);
    if (a < 0.0 || b < 0.0 || a > s.su || b > s.sv) continue;
    best = t;
    hit->t = t;
    hit->surface = s.index;
    hit->a = a;
    hit->b = b;
    hit->cos_incidence = -denom;
  }
  return hit->surface >= 0;
}

template <typename Fn>
void Renderer::ForEachPixel(const SE3& world_from_cam, Fn&& fn) const {
  const FrameSetup f = Setup(world_from_cam, true);
  const int T = options_.tile_px;
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      const size_t k = static_cast<size_t>(ty) * tiles_x_ + tx;
      const PackedSurface* cand = f.cand.data() + f.tile_begin[k];
      const int n_cand = f.tile_begin[k + 1] - f.tile_begin[k];
      const int x1 = std::min(width_, (tx + 1) * T), y1 = std::min(height_, (ty + 1) * T);
      for (int y = ty * T; y < y1; ++y)
        for (int x = tx * T; x < x1; ++x) {
          const size_t i = static_cast<size_t>(y) * width_ + x;
          if (!valid_[i]) {
            fn(i, nullptr, false);
            continue;
          }
          Hit hit;
          const bool ok = Trace(cand, n_cand, f.R * bearing_[i], &hit);
          fn(i, ok ? &hit : nullptr, true);
        }
    }
}

cv::Mat Renderer::RenderRadiance(const SE3& world_from_cam) const {
  cv::Mat out(height_, width_, CV_32F);
  float* px = out.ptr<float>();
  const auto& surfaces = world_->surfaces();
  const auto& textures = world_->textures();
  const float background = world_->background_grey();
  const float lod_bias = static_cast<float>(options_.lod_bias);
  const float aniso = static_cast<float>(options_.anisotropy);
  ForEachPixel(world_from_cam, [&](size_t i, const Hit* hit, bool valid) {
    if (!valid) { px[i] = 0.0f; return; }
    if (hit == nullptr) { px[i] = background * vignette_[i]; return; }
    const Surface& s = surfaces[hit->surface];
    const MipTexture& tex = textures[s.texture];
    // Footprint of the pixel on the surface in texels; the oblique axis is stretched by
    // 1/cos(incidence), `anisotropy` picks between the short and the long axis.
    const float footprint = static_cast<float>(hit->t) * pixel_angle_[i] * tex.inv_texel_m();
    const float stretch = 1.0f / std::max(static_cast<float>(hit->cos_incidence), 1e-3f);
    const float lod = FastLog2(std::max(footprint, 1e-6f)) + aniso * FastLog2(stretch) + lod_bias;
    // Texture images are drawn x right / y down, seen from the front, and u x v points
    // towards the viewer: mirror u so that marks (text) are not mirrored.
    px[i] = tex.Sample(s.size_u_m - hit->a, hit->b, lod) * s.albedo * vignette_[i];
  });
  return out;
}

cv::Mat Renderer::Render(const std::vector<SE3>& poses, float gain, std::uint64_t noise_key) const {
  cv::Mat radiance = RenderRadiance(poses.at(0));
  for (size_t k = 1; k < poses.size(); ++k) radiance += RenderRadiance(poses[k]);
  const float scale = gain / static_cast<float>(poses.size());
  cv::Mat out(height_, width_, CV_8UC1);
  const float* in = radiance.ptr<float>();
  unsigned char* o = out.ptr<unsigned char>();
  const float read2 = static_cast<float>(options_.read_noise_dn * options_.read_noise_dn);
  const float shot = static_cast<float>(options_.shot_noise_gain);
  const bool noisy = read2 > 0.0f || shot > 0.0f;
  const std::uint64_t key = HashMix(noise_key);
  for (size_t i = 0, n = static_cast<size_t>(width_) * height_; i < n; ++i) {
    float v = in[i] * scale;
    if (noisy && valid_[i]) v += std::sqrt(read2 + shot * std::max(v, 0.0f)) * HashNormal(HashCombine(key, i));
    o[i] = static_cast<unsigned char>(std::clamp(v, 0.0f, 255.0f) + 0.5f);  // round half up
  }
  return out;
}

std::optional<RayHit> Renderer::CastRay(const SE3& world_from_cam, const Eigen::Vector2d& uv) const {
  return CastRays(world_from_cam, {uv}).front();
}

std::vector<std::optional<RayHit>> Renderer::CastRays(const SE3& world_from_cam,
                                                      const std::vector<Eigen::Vector2d>& uvs) const {
  const FrameSetup f = Setup(world_from_cam, false);
  std::vector<std::optional<RayHit>> out(uvs.size());
  for (size_t i = 0; i < uvs.size(); ++i) {
    Eigen::Vector3d b;
    if (!camera_->Unproject(uvs[i], &b) || !std::isfinite(b.norm())) continue;
    Hit hit;
    const Eigen::Vector3d d = f.R * b.normalized();
    if (!Trace(f.visible.data(), static_cast<int>(f.visible.size()), d, &hit)) continue;
    RayHit r;
    r.range_m = hit.t;
    r.point_w = f.center + hit.t * d;
    r.depth_m = hit.t * b.normalized().z();
    r.surface = hit.surface;
    r.surface_uv_m = Eigen::Vector2d(hit.a, hit.b);
    out[i] = r;
  }
  return out;
}

void Renderer::RenderDepth(const SE3& world_from_cam, cv::Mat* depth_m, cv::Mat* surface) const {
  *depth_m = cv::Mat(height_, width_, CV_32F, cv::Scalar(0.0f));
  *surface = cv::Mat(height_, width_, CV_32S, cv::Scalar(-1));
  float* d = depth_m->ptr<float>();
  int* s = surface->ptr<int>();
  ForEachPixel(world_from_cam, [&](size_t i, const Hit* hit, bool) {
    if (hit == nullptr) return;
    d[i] = static_cast<float>(hit->t * bearing_[i].z());
    s[i] = hit->surface;
  });
}

}  // namespace ccm::sim
