// A server back-end with hand-built maps for the map view's tests and benchmark: keyframes
// along a line per agent, points seen by consecutive keyframes (so the Map computes real
// covisibility edges). The fixture owns the map stack and starts the back-end from it
// (ServerBackend's restoring constructor), then keeps editing it as registration would; the
// back-end runs no stage meanwhile. No VO, no vocabulary.
#pragma once

#include <memory>
#include <unordered_map>
#include <vector>

#include "slam_core/server/server_backend.h"
#include "tests/slam_core/map/map_fixture.h"

namespace ccm::testing {

class ViewBackend {
 public:
  /// `keypoints` per keyframe bounds the points a keyframe can observe.
  explicit ViewBackend(int keypoints = 200)
      : stack_(std::make_shared<MapStack>(ServerOptions{}.map)),
        backend_(std::make_shared<Vocabulary>(), ServerOptions{}, RestoredStack{stack_, {}}), camera_(TestCamera()),
        pyramid_(std::make_shared<ScalePyramid>(ScalePyramid::Make(8, 1.2))), keypoints_(keypoints) {}

  ServerBackend& backend() { return backend_; }
  /// The stack the back-end reads: what a fusion would edit (Repoint) is done here.
  MapStack& map_stack() { return *stack_; }

  /// The server map of agent `agent`'s first segment (created on first use).
  std::shared_ptr<ServerMap> MapOf(AgentId agent) {
    return stack_->MapFor(agent, MapId::Make(agent, 1));
  }

  /// Adds a keyframe of `agent` at x = `x_m` (looking along +z) and `new_points` points seen
  /// by it and by the agent's previous keyframe (the covisibility weight of their edge).
  KeyframeId AddKeyframe(AgentId agent, double x_m, int new_points) {
    auto map = MapOf(agent);
    auto f = std::make_shared<FrameFeatures>();
    for (int i = 0; i < keypoints_; ++i) {
      Keypoint kp;
      kp.u = static_cast<float>(10 + (i * 37) % 700);
      kp.v = static_cast<float>(10 + (i * 53) % 460);
      f->keypoints.push_back(kp);
      f->descriptors.push_back(OrbDescriptor{});
    }
    auto& counters = counters_[agent];
    const KeyframeId id = KeyframeId::Make(agent, ++counters.first);
    map->map().AddKeyframe(std::make_shared<KeyFrame>(id, static_cast<int64_t>(id.counter()) * 50000000, camera_, f,
                                                      pyramid_, SE3(Eigen::Quaterniond::Identity(), {x_m, 0, 0})));
    const KeyframeId prev = last_[agent];
    ServerKeyframeInfo info;  // as registration records it (AgentTrajectory reads it)
    info.segment = MapId::Make(agent, 1);
    info.predecessor = prev;
    map->SetInfo(id, info);
    for (int i = 0; i < new_points; ++i) {
      const MapPointId mp = MapPointId::Make(agent, ++counters.second);
      map->map().AddMapPoint(std::make_shared<MapPoint>(mp, Eigen::Vector3d(x_m + 0.01 * i, 0.5, 5), id, OrbDescriptor{}));
      map->map().AddObservation(id, next_kp_[id]++, mp);
      if (prev.valid() && next_kp_[prev] < keypoints_) map->map().AddObservation(prev, next_kp_[prev]++, mp);
    }
    map->map().UpdateConnections(id);
    stack_->EditHandler(agent, MapId::Make(agent, 1), [id](AgentHandler* h) {
      h->last_keyframe = id;
      ++h->keyframes;
    });
    last_[agent] = id;
    return id;
  }

 private:
  std::shared_ptr<MapStack> stack_;
  ServerBackend backend_;
  std::shared_ptr<const CameraModel> camera_;
  std::shared_ptr<const ScalePyramid> pyramid_;
  int keypoints_;
  std::unordered_map<AgentId, std::pair<uint64_t, uint64_t>> counters_;  // keyframe, point counters
  std::unordered_map<AgentId, KeyframeId> last_;
  std::unordered_map<KeyframeId, int> next_kp_;
};

}  // namespace ccm::testing
