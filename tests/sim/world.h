// The simulated 3D world: one-sided planar rectangles ("surfaces"), each with its own
// procedural texture. Rooms face inwards, boxes and pillars outwards, so back-face
// culling is exact for closed objects. Built once from a WorldSpec; immutable afterwards
// and shared (shared_ptr<const World>) by every renderer and agent.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tests/sim/texture.h"

namespace ccm::sim {

/// A textured rectangle: points origin + a * axis_u + b * axis_v, a in [0, size_u_m],
/// b in [0, size_v_m]. Visible only from the side its normal (axis_u x axis_v) points to.
struct Surface {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX();  ///< unit
  Eigen::Vector3d axis_v = Eigen::Vector3d::UnitY();  ///< unit, orthogonal to axis_u
  double size_u_m = 1.0;
  double size_v_m = 1.0;
  int texture = 0;          ///< index into World::textures()
  float albedo = 1.0f;      ///< multiplies the texture (lighting differences between faces)
  int object = 0;           ///< index of the WorldSpec object that created it
  std::string name;         ///< e.g. "hall/floor", "box3/+x", for messages and tests

  Eigen::Vector3d normal() const { return axis_u.cross(axis_v); }
  Eigen::Vector3d center() const { return origin + 0.5 * size_u_m * axis_u + 0.5 * size_v_m * axis_v; }
};

enum class ObjectKind { kRoom = 0, kBox = 1, kPillar = 2, kPanel = 3 };

/// One element of a world description.
/// kRoom: axis-aligned box [min, max] seen from inside (floor, ceiling, 4 walls).
/// kBox / kPillar: box standing on z = min.z() seen from outside (4 sides + top), with
///   `yaw_deg` rotation about its vertical centre axis (pillars are just tall boxes).
/// kPanel: a free rectangle centred at `min` with normal `normal`, size max.x() x max.y()
///   (markers, posters).
struct ObjectSpec {
  ObjectKind kind = ObjectKind::kBox;
  std::string name;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Ones();
  double yaw_deg = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();  ///< kPanel only
  TextureStyle style = TextureStyle::kMixed;
  /// Per-face styles for rooms: floor, ceiling, walls (empty => `style` everywhere).
  std::vector<TextureStyle> room_styles;
  float grey = 128.0f;          ///< mean grey level of the texture (kFlat: the value)
  /// Objects with the same non-empty share_key reuse one texture per face index
  /// (deliberately repeated structures). Empty => unique textures.
  std::string share_key;
};

struct WorldSpec {
  std::vector<ObjectSpec> objects;
  double texel_m = 0.008;        ///< texture resolution at mip level 0 [m]
  float background_grey = 90.0f; ///< grey value of rays that hit nothing
  std::string Validate() const;  ///< empty if usable, else the first problem
};

/// Immutable world: surfaces + textures. Thread-safe to read.
class World {
 public:
  /// Builds surfaces and draws textures; deterministic in (spec, seed).
  World(const WorldSpec& spec, std::uint64_t seed);

  const std::vector<Surface>& surfaces() const { return surfaces_; }
  const std::vector<MipTexture>& textures() const { return textures_; }
  const WorldSpec& spec() const { return spec_; }
  float background_grey() const { return spec_.background_grey; }

 private:
  void AddObject(const ObjectSpec& obj, int object_index, std::uint64_t seed);
  int TextureFor(const ObjectSpec& obj, int object_index, int face, const Surface& s, TextureStyle style,
                 std::uint64_t seed);

  WorldSpec spec_;
  std::vector<Surface> surfaces_;
  std::vector<MipTexture> textures_;
  std::vector<std::pair<std::string, int>> shared_textures_;  // "key/face" -> texture index
};

}  // namespace ccm::sim
