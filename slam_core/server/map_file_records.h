// The records of a map stack file (map_persistence.cc): the payload is one StackRecord in a
// cereal portable binary archive. Internal to map_persistence.cc; its own header only to keep
// the loader's file short. Changing a record changes the file format (kMapStackVersion) and
// tests/slam_core/server/map_file_mutator.h's walker, which mirrors this layout.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <cereal/archives/portable_binary.hpp>
#include <cereal/types/array.hpp>
#include <cereal/types/utility.hpp>

namespace ccm::map_file {

using Pose7 = std::array<double, 7>;  // qx qy qz qw tx ty tz

// A vector or string as cereal writes it (size, then the elements: the same bytes), read so
// that memory grows only with the elements the file really holds: a crafted size field
// cannot make the loader allocate (cereal would resize to it first). Every vector and
// string of the records below goes through it.
template <class C>
struct Bounded {
  C& c;
  template <class A>
  void save(A& a) const {
    a(cereal::make_size_tag(static_cast<cereal::size_type>(c.size())));
    for (const auto& x : c) a(x);
  }
  template <class A>
  void load(A& a) {
    cereal::size_type n = 0;
    a(cereal::make_size_tag(n));
    c.clear();
    for (cereal::size_type i = 0; i < n; ++i) {  // a short payload throws at its end
      typename C::value_type x{};
      a(x);
      c.push_back(std::move(x));
    }
  }
};
template <class C>
Bounded<C> B(C& c) {
  return {c};
}

// A bool as cereal writes it (one byte). Read as a byte first: any other value than 0 or 1
// loaded into a bool is undefined behaviour (UBSan: "not a valid value for type 'bool'").
struct Flag {
  bool& b;
  template <class A>
  void save(A& a) const {
    a(static_cast<uint8_t>(b ? 1 : 0));
  }
  template <class A>
  void load(A& a) {
    uint8_t v = 0;
    a(v);
    if (v > 1) throw cereal::Exception("a flag byte of " + std::to_string(v));
    b = v == 1;
  }
};

struct CameraRecord {
  int type = 0, width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::vector<double> distortion;
  template <class A>
  void serialize(A& a) {
    a(type, width, height, fx, fy, cx, cy, B(distortion));
  }
  bool operator<(const CameraRecord& o) const {
    return std::tie(type, width, height, fx, fy, cx, cy, distortion) <
           std::tie(o.type, o.width, o.height, o.fx, o.fy, o.cx, o.cy, o.distortion);
  }
};

struct InfoRecord {
  uint64_t segment = 0, predecessor = 0, parent = 0;
  Pose7 pred_from_cam{}, parent_from_cam{}, segment_from_cam{};
  bool settled = false;
  template <class A>
  void serialize(A& a) {
    a(segment, predecessor, parent, pred_from_cam, parent_from_cam, segment_from_cam, Flag{settled});
  }
};

struct KeyframeRecord {
  uint64_t id = 0;
  int64_t stamp_ns = 0;
  uint32_t camera = 0;  // index into StackRecord::cameras
  int levels = 8;
  double scale_factor = 1.2;
  std::vector<float> kp;  // u v angle response per keypoint
  std::vector<int8_t> kp_level;
  std::vector<std::array<uint8_t, 32>> descriptors;
  std::vector<uint64_t> map_points;  // per keypoint, 0 = none
  Pose7 pose{};
  uint64_t parent = 0;
  std::vector<uint64_t> children, loop_edges;
  std::vector<std::pair<uint64_t, int>> covisibility;
  bool has_info = false;
  InfoRecord info;
  template <class A>
  void serialize(A& a) {
    a(id, stamp_ns, camera, levels, scale_factor, B(kp), B(kp_level), B(descriptors), B(map_points), pose, parent,
      B(children), B(loop_edges), B(covisibility), Flag{has_info}, info);
  }
};

struct PointRecord {
  uint64_t id = 0, reference = 0;
  std::array<double, 3> position{}, normal{};
  std::array<uint8_t, 32> descriptor{};
  double min_distance = 0, max_distance = 0;
  std::vector<std::pair<uint64_t, int>> observations;
  template <class A>
  void serialize(A& a) {
    a(id, reference, position, normal, descriptor, min_distance, max_distance, B(observations));
  }
};

struct AnchorRecord {
  uint64_t id = 0, base = 0, segment = 0;
  Pose7 base_from_cam{};
  int64_t stamp_ns = 0;
  template <class A>
  void serialize(A& a) {
    a(id, base, segment, base_from_cam, stamp_ns);
  }
};

struct MapRecord {
  uint64_t id = 0, generation = 0;
  std::vector<KeyframeRecord> keyframes;
  std::vector<PointRecord> points;
  std::vector<AnchorRecord> anchors;
  std::vector<std::pair<uint64_t, uint64_t>> replaced;
  template <class A>
  void serialize(A& a) {
    a(id, generation, B(keyframes), B(points), B(anchors), B(replaced));
  }
};

struct HandlerRecord {
  uint16_t agent = 0;
  uint64_t segment = 0, map = 0, last_keyframe = 0;
  double s = 1.0;
  std::array<double, 7> sim{};  // qx qy qz qw tx ty tz of map_from_segment (scale in s)
  double scale = 1.0;
  int64_t keyframes = 0;
  template <class A>
  void serialize(A& a) {
    a(agent, segment, map, last_keyframe, s, sim, scale, keyframes);
  }
};

struct EventRecord {
  int kind = 0;
  double time_s = 0, seconds = 0;
  int64_t stamp_ns = 0;
  uint16_t agent = 0;
  uint64_t map = 0, other_map = 0, query = 0, candidate = 0;
  int keyframes = 0;
  std::string detail;
  template <class A>
  void serialize(A& a) {
    a(kind, time_s, seconds, stamp_ns, agent, map, other_map, query, candidate, keyframes, B(detail));
  }
};

struct StackRecord {
  uint64_t next_map = 1;
  std::vector<CameraRecord> cameras;
  std::vector<MapRecord> maps;
  std::vector<HandlerRecord> handlers;
  std::vector<EventRecord> events;
  template <class A>
  void serialize(A& a) {
    a(next_map, B(cameras), B(maps), B(handlers), B(events));
  }
};

}  // namespace ccm::map_file
