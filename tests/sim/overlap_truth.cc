#include "tests/sim/overlap_truth.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

namespace ccm::sim {
namespace {

std::uint64_t CellKey(int surface, const Eigen::Vector2d& uv, double cell_m) {
  const auto iu = static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(uv.x() / cell_m)) & 0xFFFFFF);
  const auto iv = static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(uv.y() / cell_m)) & 0xFFFFFF);
  return (static_cast<std::uint64_t>(surface) << 48) | (iu << 24) | iv;
}

double Median(std::vector<double>* v) {
  if (v->empty()) return 0.0;
  std::nth_element(v->begin(), v->begin() + v->size() / 2, v->end());
  return (*v)[v->size() / 2];
}

}  // namespace

SampledView OverlapTruth::Sample(const Simulation& sim, const SE3& world_from_cam, double time_s) const {
  const CameraModel& cam = sim.renderer().camera();
  std::vector<Eigen::Vector2d> uvs;
  for (int r = 0; r < options_.grid_rows; ++r) {
    for (int c = 0; c < options_.grid_cols; ++c) {
      uvs.emplace_back((c + 0.5) * cam.width() / options_.grid_cols, (r + 0.5) * cam.height() / options_.grid_rows);
    }
  }
  SampledView v;
  v.time_s = time_s;
  v.world_from_cam = world_from_cam;
  struct Ray {
    std::uint64_t key;
    Eigen::Vector3f dir;
    float range;
  };
  std::vector<Ray> rays;
  const Eigen::Vector3d center = world_from_cam.translation();
  for (const auto& hit : sim.renderer().CastRays(world_from_cam, uvs)) {
    if (!hit) continue;
    rays.push_back({CellKey(hit->surface, hit->surface_uv_m, options_.cell_m),
                    ((hit->point_w - center) / hit->range_m).cast<float>(), static_cast<float>(hit->range_m)});
  }
  std::stable_sort(rays.begin(), rays.end(), [](const Ray& x, const Ray& y) { return x.key < y.key; });
  v.rays = static_cast<int>(rays.size());
  for (const Ray& r : rays) {
    if (!v.cells.empty() && v.cells.back() == r.key) {
      ++v.counts.back();
      continue;
    }
    v.cells.push_back(r.key);
    v.dirs.push_back(r.dir);
    v.ranges.push_back(r.range);
    v.counts.push_back(1);
  }
  return v;
}

ViewOverlap OverlapTruth::Compare(const SampledView& a, const SampledView& b) const {
  return Compare(a, b, options_.max_ray_angle_deg, options_.max_range_ratio);
}

bool OverlapTruth::MayShareSurface(const SampledView& a, const SampledView& b) const {
  const ViewOverlap o = Compare(a, b, 90.0, 10.0);
  return std::min(o.share_a, o.share_b) > 0.0;
}

ViewOverlap OverlapTruth::Compare(const SampledView& a, const SampledView& b, double max_ray_angle_deg,
                                  double max_range_ratio) const {
  ViewOverlap o;
  if (a.rays == 0 || b.rays == 0) return o;
  const float cos_max = static_cast<float>(std::cos(max_ray_angle_deg * M_PI / 180.0));
  const float ratio = static_cast<float>(max_range_ratio);
  int rays_a = 0, rays_b = 0;
  std::vector<double> angles;
  for (size_t i = 0, j = 0; i < a.cells.size() && j < b.cells.size();) {
    if (a.cells[i] < b.cells[j]) {
      ++i;
    } else if (b.cells[j] < a.cells[i]) {
      ++j;
    } else {
      const float c = a.dirs[i].dot(b.dirs[j]);
      const float r = a.ranges[i] > b.ranges[j] ? a.ranges[i] / b.ranges[j] : b.ranges[j] / a.ranges[i];
      if (c >= cos_max && r <= ratio) {
        rays_a += a.counts[i];
        rays_b += b.counts[j];
        angles.push_back(std::acos(std::min(1.0f, c)) * 180.0 / M_PI);
      }
      ++i, ++j;
    }
  }
  o.share_a = static_cast<double>(rays_a) / a.rays;
  o.share_b = static_cast<double>(rays_b) / b.rays;
  o.angle_deg = Median(&angles);
  o.covisible = std::min(o.share_a, o.share_b) >= options_.min_shared;
  return o;
}

OverlapTruth OverlapTruth::Compute(const Simulation& sim, const OverlapTruthOptions& options) {
  OverlapTruth t;
  t.options_ = options;
  const double dt = 1.0 / options.sample_hz;
  for (int a = 0; a < sim.num_agents(); ++a) {
    const Trajectory& traj = sim.trajectory(a);
    std::vector<SampledView> views;
    for (double time = 0.0; time <= traj.duration_s() + 1e-9; time += dt) {
      views.push_back(t.Sample(sim, traj.WorldFromCam(time), time));
    }
    t.views_.push_back(std::move(views));
    AgentTruth at;
    at.path_m = traj.ArcLength(traj.duration_s());
    // Revisits: own views far apart in time that see the same place.
    std::set<size_t> later;
    for (size_t i = 0; i < t.views_[a].size(); ++i) {
      for (size_t j = i + 1; j < t.views_[a].size(); ++j) {
        const SampledView &x = t.views_[a][i], &y = t.views_[a][j];
        if (y.time_s - x.time_s < options.revisit_gap_s) continue;
        const ViewOverlap o = t.Compare(x, y);
        if (!o.covisible || o.angle_deg > options.qualify_angle_deg) continue;
        if (later.insert(j).second && (at.first_revisit_s < 0 || y.time_s < at.first_revisit_s)) {
          at.first_revisit_s = y.time_s;
        }
      }
    }
    at.revisits = static_cast<double>(later.size()) * dt >= 2.0;
    t.agents_.push_back(at);
  }
  for (int a = 0; a < sim.num_agents(); ++a) {
    for (int b = a + 1; b < sim.num_agents(); ++b) {
      PairTruth p;
      p.a = a, p.b = b;
      std::set<size_t> seen_a, seen_b;
      std::vector<double> angles;
      for (size_t i = 0; i < t.views_[a].size(); ++i) {
        for (size_t j = 0; j < t.views_[b].size(); ++j) {
          const SampledView &x = t.views_[a][i], &y = t.views_[b][j];
          const ViewOverlap o = t.Compare(x, y);
          if (!o.covisible) continue;
          p.overlaps = true;
          angles.push_back(o.angle_deg);
          if (o.angle_deg > options.qualify_angle_deg) continue;
          seen_a.insert(i);
          seen_b.insert(j);
          const double both = std::max(x.time_s, y.time_s);
          if (p.first_s < 0 || both < p.first_s) p.first_s = both;
        }
      }
      p.seconds_a = static_cast<double>(seen_a.size()) * dt;
      p.seconds_b = static_cast<double>(seen_b.size()) * dt;
      p.median_angle_deg = Median(&angles);
      p.qualifies = std::min(p.seconds_a, p.seconds_b) >= options.qualify_seconds;
      if (!p.overlaps) p.kind = "none";
      else if (std::min(p.seconds_a, p.seconds_b) < options.qualify_seconds) p.kind = "brief";
      else p.kind = p.median_angle_deg <= 25.0 ? "same" : "oblique";
      t.pairs_.push_back(p);
    }
  }
  return t;
}

const PairTruth& OverlapTruth::pair(int a, int b) const {
  if (a > b) std::swap(a, b);
  for (const PairTruth& p : pairs_) {
    if (p.a == a && p.b == b) return p;
  }
  throw std::out_of_range("OverlapTruth::pair: no such pair");
}

}  // namespace ccm::sim
