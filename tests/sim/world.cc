#include "tests/sim/world.h"

#include <cmath>

#include <Eigen/Geometry>

#include "tests/sim/sim_random.h"

namespace ccm::sim {

std::string WorldSpec::Validate() const {
  if (!(texel_m > 1e-4 && texel_m < 1.0)) return "texel_m must be in (0.0001, 1) m";
  if (objects.empty()) return "world has no objects";
  for (size_t i = 0; i < objects.size(); ++i) {
    const ObjectSpec& o = objects[i];
    const std::string where = "object " + std::to_string(i) + " ('" + o.name + "')";
    if (o.kind == ObjectKind::kPanel) {
      if (!(o.max.x() > 0 && o.max.y() > 0)) return where + ": panel size must be > 0";
      if (o.normal.norm() < 1e-9) return where + ": panel normal must be non-zero";
    } else if (!((o.max - o.min).minCoeff() > 0.0)) {
      return where + ": max must be greater than min in x, y and z";
    }
    if (o.kind == ObjectKind::kRoom && !o.room_styles.empty() && o.room_styles.size() != 3)
      return where + ": room_styles needs 3 entries (floor, ceiling, walls)";
    if (!(o.grey >= 0.0f && o.grey <= 255.0f)) return where + ": grey must be in [0, 255]";
  }
  return {};
}

namespace {

Surface MakeSurface(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v, double su,
                    double sv) {
  Surface s;
  s.origin = origin;
  s.axis_u = u.normalized();
  s.axis_v = v.normalized();
  s.size_u_m = su;
  s.size_v_m = sv;
  return s;
}

// Faces of an axis-aligned room seen from inside: floor, ceiling, then 4 walls.
std::vector<Surface> RoomFaces(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d d = b - a;
  std::vector<Surface> f;
  f.push_back(MakeSurface(a, X, Y, d.x(), d.y()));
  f.push_back(MakeSurface({a.x(), b.y(), b.z()}, X, -Y, d.x(), d.y()));
  f.push_back(MakeSurface({a.x(), a.y(), b.z()}, X, -Z, d.x(), d.z()));
  f.push_back(MakeSurface({b.x(), b.y(), b.z()}, -X, -Z, d.x(), d.z()));
  f.push_back(MakeSurface({a.x(), b.y(), b.z()}, -Y, -Z, d.y(), d.z()));
  f.push_back(MakeSurface({b.x(), a.y(), b.z()}, Y, -Z, d.y(), d.z()));
  return f;
}

// Faces of a yawed box seen from outside: 4 sides, top, and bottom if it floats.
std::vector<Surface> BoxFaces(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double yaw_deg) {
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d h = 0.5 * (b - a);
  const double hx = h.x(), hy = h.y(), top = b.z(), bottom = a.z();
  std::vector<Surface> f;
  f.push_back(MakeSurface({hx, hy, top}, -Y, -Z, 2 * hy, 2 * h.z()));
  f.push_back(MakeSurface({-hx, -hy, top}, Y, -Z, 2 * hy, 2 * h.z()));
  f.push_back(MakeSurface({-hx, hy, top}, X, -Z, 2 * hx, 2 * h.z()));
  f.push_back(MakeSurface({hx, -hy, top}, -X, -Z, 2 * hx, 2 * h.z()));
  f.push_back(MakeSurface({-hx, -hy, top}, X, Y, 2 * hx, 2 * hy));
  if (bottom > 0.01) f.push_back(MakeSurface({-hx, hy, bottom}, X, -Y, 2 * hx, 2 * hy));
  const double yaw = yaw_deg * M_PI / 180.0;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Z).toRotationMatrix();
  const Eigen::Vector3d c(0.5 * (a.x() + b.x()), 0.5 * (a.y() + b.y()), 0.0);
  for (Surface& s : f) {
    s.origin = R * s.origin + c;
    s.axis_u = R * s.axis_u;
    s.axis_v = R * s.axis_v;
  }
  return f;
}

Surface PanelFace(const ObjectSpec& o) {
  const Eigen::Vector3d n = o.normal.normalized();
  Eigen::Vector3d u = Eigen::Vector3d::UnitZ().cross(n);
  if (u.norm() < 1e-6) u = Eigen::Vector3d::UnitX();
  u.normalize();
  const Eigen::Vector3d v = n.cross(u);
  return MakeSurface(o.min - 0.5 * o.max.x() * u - 0.5 * o.max.y() * v, u, v, o.max.x(), o.max.y());
}

}  // namespace

World::World(const WorldSpec& spec, std::uint64_t seed) : spec_(spec) {
  for (size_t i = 0; i < spec_.objects.size(); ++i) AddObject(spec_.objects[i], static_cast<int>(i), seed);
}

void World::AddObject(const ObjectSpec& obj, int object_index, std::uint64_t seed) {
  std::vector<Surface> faces;
  if (obj.kind == ObjectKind::kRoom) faces = RoomFaces(obj.min, obj.max);
  else if (obj.kind == ObjectKind::kPanel) faces = {PanelFace(obj)};
  else faces = BoxFaces(obj.min, obj.max, obj.yaw_deg);
  static const char* kRoomFaceNames[] = {"floor", "ceiling", "wall-y0", "wall-y1", "wall-x0", "wall-x1"};
  static const char* kBoxFaceNames[] = {"+x", "-x", "+y", "-y", "top", "bottom"};
  for (size_t f = 0; f < faces.size(); ++f) {
    Surface s = faces[f];
    TextureStyle style = obj.style;
    if (obj.kind == ObjectKind::kRoom && obj.room_styles.size() == 3)
      style = obj.room_styles[f == 0 ? 0 : (f == 1 ? 1 : 2)];
    s.object = object_index;
    const char* face_name = obj.kind == ObjectKind::kRoom ? kRoomFaceNames[f] : kBoxFaceNames[f];
    s.name = (obj.name.empty() ? "object" + std::to_string(object_index) : obj.name) + "/" + face_name;
    // Lighting: a fixed, face-dependent albedo (floors a bit darker, tops brighter).
    const std::uint64_t h = HashCombine(seed, static_cast<std::uint64_t>(object_index) * 16 + f);
    s.albedo = static_cast<float>(0.8 + 0.3 * static_cast<double>(h & 0xFFFF) / 65535.0);
    if (style == TextureStyle::kFlat) s.albedo = 1.0f;
    s.texture = TextureFor(obj, object_index, static_cast<int>(f), s, style, seed);
    surfaces_.push_back(s);
  }
}

int World::TextureFor(const ObjectSpec& obj, int object_index, int face, const Surface& s, TextureStyle style,
                      std::uint64_t seed) {
  std::string key;
  if (!obj.share_key.empty()) {
    key = obj.share_key + "/" + std::to_string(face);
    for (const auto& [k, index] : shared_textures_)
      if (k == key) return index;
  }
  TextureRecipe recipe;
  recipe.style = style;
  recipe.width_m = s.size_u_m;
  recipe.height_m = s.size_v_m;
  // Weakly textured faces carry little detail: a coarser texel saves memory and time.
  recipe.texel_m = style == TextureStyle::kWeak ? 2.0 * spec_.texel_m : spec_.texel_m;
  if (style == TextureStyle::kFlat) recipe.texel_m = std::max(s.size_u_m, s.size_v_m) / 8.0;
  recipe.base_grey = obj.grey;
  recipe.seed = key.empty() ? HashCombine(seed, static_cast<std::uint64_t>(object_index) * 16 + face)
                            : HashCombine(seed, StringHash(key.c_str()));
  textures_.emplace_back(DrawProceduralTexture(recipe), recipe.texel_m);
  const int index = static_cast<int>(textures_.size()) - 1;
  if (!key.empty()) shared_textures_.emplace_back(key, index);
  return index;
}

}  // namespace ccm::sim
