// Builds small maps with exactly known sharing between keyframes for the map tests.
#pragma once

#include <memory>
#include <random>
#include <unordered_map>
#include <vector>

#include "slam_core/map/map.h"

namespace ccm::testing {

inline std::shared_ptr<const CameraModel> TestCamera() {
  CameraIntrinsics c;
  c.width_px = 752;
  c.height_px = 480;
  c.fx = c.fy = 458.0;
  c.cx = 376.0;
  c.cy = 240.0;
  return std::shared_ptr<const CameraModel>(MakeCamera(c));
}

class MapBuilder {
 public:
  explicit MapBuilder(int keypoints_per_kf = 600)
      : map_(MapId::Make(1, 1)), mp_ids_(1), camera_(TestCamera()),
        pyramid_(std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2))), kps_(keypoints_per_kf) {}

  Map& map() { return map_; }

  /// Adds a keyframe at x = index metres looking along +z, with random descriptors.
  KeyframeId AddKeyframe(double x_m) { return AddKeyframeAt({x_m, 0, 0}); }

  /// Adds a keyframe of `agent` centred at `centre` looking along +z.
  KeyframeId AddKeyframeAt(const Eigen::Vector3d& centre, AgentId agent = 1) {
    auto f = std::make_shared<FrameFeatures>();
    for (int i = 0; i < kps_; ++i) {
      Keypoint kp;
      kp.u = static_cast<float>(10 + (i * 37) % 700);
      kp.v = static_cast<float>(10 + (i * 53) % 460);
      kp.level = i % 8;
      f->keypoints.push_back(kp);
      OrbDescriptor d;
      for (auto& b : d) b = static_cast<uint8_t>(rng_());
      f->descriptors.push_back(d);
    }
    const KeyframeId id = kf_ids_.try_emplace(agent, agent).first->second.Next();
    map_.AddKeyframe(std::make_shared<KeyFrame>(id, static_cast<int64_t>(id.counter()) * 50000000, camera_, f,
                                                pyramid_, SE3(Eigen::Quaterniond::Identity(), centre)));
    next_kp_[id] = 0;
    return id;
  }

  /// Adds a map point observed by all `kfs` (next free keypoint in each).
  MapPointId AddPointSeenBy(const std::vector<KeyframeId>& kfs, Eigen::Vector3d p = {0, 0, 5}) {
    const MapPointId id = mp_ids_.Next();
    map_.AddMapPoint(std::make_shared<MapPoint>(id, p, kfs.front(), OrbDescriptor{}));
    for (const KeyframeId kf : kfs) map_.AddObservation(kf, next_kp_[kf]++, id);
    return id;
  }

  void AddSharedPoints(const std::vector<KeyframeId>& kfs, int n) {
    for (int i = 0; i < n; ++i) AddPointSeenBy(kfs);
  }

 private:
  Map map_;
  std::unordered_map<AgentId, IdGenerator<KeyframeId>> kf_ids_;
  IdGenerator<MapPointId> mp_ids_;
  std::shared_ptr<const CameraModel> camera_;
  std::shared_ptr<const ScalePyramid> pyramid_;
  int kps_;
  std::mt19937 rng_{42};
  std::unordered_map<KeyframeId, int> next_kp_;
};

}  // namespace ccm::testing
