// SceneBuilder's objects: boxes, pillars and panels as YAML lines with their footprints,
// and the filler objects placed off every flight path.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "tests/sim/scene_layout.h"

namespace ccm::sim {
namespace {
using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
}  // namespace

const char* ObjectStyleForProfile(Rng* rng, int profile) {
  const double x = rng->Uniform();
  if (profile == 0) return x < 0.85 ? "rich" : "mixed";
  if (profile == 1) return x < 0.55 ? "rich" : "mixed";
  return x < 0.25 ? "rich" : (x < 0.8 ? "mixed" : "weak");
}

void SceneBuilder::AddBox(const std::string& type, const std::string& name, const Vec2& c, const Vec3& size,
                          double yaw_deg, const std::string& style, double base_z) {
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "{type: %s, name: %s, center: [%.3f, %.3f], size: [%.3f, %.3f, %.3f], base_z: %.3f, yaw_deg: %.1f, "
                "style: %s, grey: %.0f}",
                type.c_str(), name.c_str(), c.x(), c.y(), size.x(), size.y(), size.z(), base_z, yaw_deg, style.c_str(),
                rng_->Uniform(85.0, 175.0));
  objects_.push_back(buf);
  Obstacle o;
  o.center = c;
  o.half = 0.5 * size.head<2>();
  o.yaw_rad = yaw_deg * M_PI / 180.0;
  o.top = base_z + size.z();
  obstacles_.push_back(o);
}

void SceneBuilder::AddPanel(const std::string& name, const Vec3& c, const Vec3& normal, double w, double h,
                            const std::string& style) {
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "{type: panel, name: %s, center: [%.3f, %.3f, %.3f], normal: [%.3f, %.3f, %.3f], size: [%.3f, %.3f], "
                "style: %s, grey: %.0f}",
                name.c_str(), c.x(), c.y(), c.z(), normal.x(), normal.y(), normal.z(), w, h, style.c_str(),
                rng_->Uniform(80.0, 180.0));
  objects_.push_back(buf);
}

bool SceneBuilder::InSpace(const Vec2& p, double margin) const {
  return p.x() >= margin && p.y() >= margin && p.x() <= space_.x() - margin && p.y() <= space_.y() - margin;
}

bool SceneBuilder::Blocks(const Obstacle& o, double margin) const {
  for (const Obstacle& other : obstacles_) {
    if ((o.center - other.center).norm() < o.half.norm() + other.half.norm() + 0.3) return true;
  }
  for (const Vec3& s : path_samples_) {
    if (s.z() - 0.5 < o.top && o.Contains(s.head<2>(), margin)) return true;
  }
  return false;
}

bool SceneBuilder::TryPlace(const std::string& type, const std::string& name, const Vec2& c, const Vec3& size,
                            double yaw_deg, const std::string& style) {
  Obstacle o;
  o.center = c;
  o.half = 0.5 * size.head<2>();
  o.yaw_rad = yaw_deg * M_PI / 180.0;
  o.top = size.z();
  if (!InSpace(c, o.half.norm() + 0.1) || Blocks(o, 0.8)) return false;
  AddBox(type, name, c, size, yaw_deg, style);
  return true;
}

void SceneBuilder::AddWallObjects(int count) {
  Rng& r = *rng_;
  const double poster_share = profile_ == 2 ? 0.25 : 0.5;
  for (int i = 0, placed = 0; i < 12 * count && placed < count; ++i) {
    const int side = r.Int(0, 3);
    const bool along_x = side < 2;
    const double len = along_x ? space_.x() : space_.y();
    const double s = r.Uniform(0.8, len - 0.8);
    const double wall = side == 0 ? 0.0 : side == 1 ? space_.y() : side == 2 ? 0.0 : space_.x();
    const double inward = (side == 0 || side == 2) ? 1.0 : -1.0;
    const std::string name = "wall_" + std::to_string(objects_.size());
    if (r.Uniform() < poster_share) {
      const double z = r.Uniform(1.0, std::max(1.1, std::min(2.4, height_ - 0.5)));
      const Vec3 c = along_x ? Vec3(s, wall + inward * 0.005, z) : Vec3(wall + inward * 0.005, s, z);
      const Vec3 n = along_x ? Vec3(0, inward, 0) : Vec3(inward, 0, 0);
      AddPanel(name, c, n, r.Uniform(0.5, 1.5), r.Uniform(0.4, 1.0), r.Uniform() < 0.7 ? "rich" : "mixed");
      ++placed;
      continue;
    }
    const double l = r.Uniform(1.5, 4.0), d = r.Uniform(0.4, 0.8);
    const double h = r.Uniform(1.2, std::max(1.3, std::min(2.4, height_ - 0.3)));
    const Vec2 c = along_x ? Vec2(s, wall + inward * (0.5 * d + 0.03)) : Vec2(wall + inward * (0.5 * d + 0.03), s);
    const Vec3 size = along_x ? Vec3(l, d, h) : Vec3(d, l, h);
    Obstacle o;
    o.center = c;
    o.half = 0.5 * size.head<2>();
    o.top = h;
    if (Blocks(o, 0.8)) continue;
    AddBox("box", name, c, size, 0.0, ObjectStyleForProfile(rng_, profile_));
    ++placed;
  }
}

void SceneBuilder::AddFillerObjects() {
  Rng& r = *rng_;
  const bool yard = layout_ == SceneLayout::kYard;
  int index = 0;
  for (const AgentPlan& a : agents_) {
    // An island in the middle of the loop: something to look at while circling.
    if (layout_ != SceneLayout::kCorridor && r.Uniform() < 0.5) {
      const double side = std::clamp(std::min(a.rx, a.ry) - 1.0, 0.4, yard ? 3.0 : 1.6);
      TryPlace("box", "island_" + std::to_string(index++), a.center, {side, side * r.Uniform(0.6, 1.0),
               yard ? r.Uniform(1.0, 3.0) : r.Uniform(0.6, 1.6)}, r.Uniform(-40.0, 40.0), ObjectStyleForProfile(rng_, profile_));
    }
    const int count = layout_ == SceneLayout::kRoom ? r.Int(1, 2) : layout_ == SceneLayout::kCorridor ? r.Int(0, 1)
                                                                                                      : r.Int(2, 4);
    for (int i = 0, placed = 0; i < 30 * count && placed < count; ++i) {
      const Vec2 c = a.cell_center + Vec2(r.Uniform(-0.5, 0.5) * cell_.x(), r.Uniform(-0.5, 0.5) * cell_.y());
      const std::string name = "object_" + std::to_string(index++);
      const double yaw = r.Uniform(-60.0, 60.0);
      bool ok = false;
      if (yard) {
        const int kind = r.Int(0, 3);
        const Vec3 size = kind == 0 ? Vec3(2.4, 6.0, 2.6) : kind == 1 ? Vec3(1.8, 4.5, 1.5)
                          : kind == 2 ? Vec3(0.3, 0.3, r.Uniform(3.0, 6.0))
                                      : Vec3(r.Uniform(1.2, 2.5), r.Uniform(1.2, 2.5), r.Uniform(1.0, 2.5));
        ok = TryPlace(kind == 2 ? "pillar" : "box", name, c, size, yaw, ObjectStyleForProfile(rng_, profile_));
      } else if (layout_ == SceneLayout::kHall && r.Uniform() < 0.3) {
        const double w = r.Uniform(0.3, 0.7);
        ok = TryPlace("pillar", name, c, {w, w, height_}, 0.0, ObjectStyleForProfile(rng_, profile_));
      } else {
        ok = TryPlace("box", name, c, {r.Uniform(0.5, 1.6), r.Uniform(0.5, 1.6), r.Uniform(0.5, 2.0)}, yaw,
                      ObjectStyleForProfile(rng_, profile_));
      }
      placed += ok;
    }
  }
  if (yard) return;
  const int wall_objects = layout_ == SceneLayout::kRoom ? r.Int(2, 4)
                           : layout_ == SceneLayout::kCorridor ? 2 * num_agents_ : r.Int(4, 8);
  AddWallObjects(wall_objects);
}

}  // namespace ccm::sim
