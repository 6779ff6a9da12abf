// Value-type test data for the conversion tests (msg_conversion_test, msg_rejection_test):
// keyframes, points, updates and server data with deterministic random content, for a
// pinhole-radtan and an equidistant-fisheye camera.
#pragma once

#include <memory>
#include <random>
#include <vector>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/exchange/server_map_data.h"

namespace ccm::testing {

inline CameraIntrinsics PinholeIntrinsics() {
  CameraIntrinsics c;
  c.type = CameraType::kPinholeRadTan;
  c.width_px = 752;
  c.height_px = 480;
  c.fx = 458.654; c.fy = 457.296; c.cx = 367.215; c.cy = 248.375;
  c.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.001};
  return c;
}

inline CameraIntrinsics FisheyeIntrinsics() {
  CameraIntrinsics c;
  c.type = CameraType::kFisheyeEquidistant;
  c.width_px = 640;
  c.height_px = 512;
  c.fx = 190.978; c.fy = 190.973; c.cx = 254.932; c.cy = 256.897;
  c.distortion = {0.0034823894, 0.000715034, -0.0020532361, 0.00020293673};
  return c;
}

inline std::shared_ptr<const CameraModel> Camera(const CameraIntrinsics& c) { return MakeCamera(c); }

inline SE3 RandomPose(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return SE3(Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)), Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

inline OrbDescriptor RandomDescriptor(std::mt19937_64& rng) {
  OrbDescriptor d;
  for (auto& b : d) b = static_cast<uint8_t>(rng());
  return d;
}

inline std::shared_ptr<const FrameFeatures> RandomFeatures(std::mt19937_64& rng, const CameraModel& camera, int n,
                                                           int levels = 8) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto f = std::make_shared<FrameFeatures>();
  for (int i = 0; i < n; ++i) {
    f->keypoints.push_back({(camera.width() - 1) * u(rng), (camera.height() - 1) * u(rng), 360.0f * u(rng),
                            100.0f * u(rng), static_cast<int>(rng() % levels)});
    f->descriptors.push_back(RandomDescriptor(rng));
  }
  return f;
}

/// Agent `agent`'s keyframe `counter` in segment 1: every third keypoint linked (some links
/// to another agent's points), predecessor counter-1, parent of agent+1.
inline KeyframeData MakeKeyframeData(AgentId agent, uint64_t counter, const CameraIntrinsics& intrinsics, int n,
                                     uint64_t seed = 1) {
  std::mt19937_64 rng(seed + counter);
  KeyframeData kf;
  kf.id = KeyframeId::Make(agent, counter);
  kf.segment = MapId::Make(agent, 1);
  kf.stamp_ns = 1'500'000'000'000'000'000LL + static_cast<int64_t>(counter) * 50'000'000;
  kf.camera = Camera(intrinsics);
  kf.features = RandomFeatures(rng, *kf.camera, n);
  for (int i = 0; i < n; i += 3) {
    const AgentId owner = i % 2 == 0 ? agent : static_cast<AgentId>(agent + 1);
    kf.point_links.emplace_back(i, MapPointId::Make(owner, 1000 + i));
  }
  kf.predecessor = counter > 1 ? KeyframeId::Make(agent, counter - 1) : KeyframeId::Invalid();
  kf.pred_from_cam = RandomPose(rng);
  kf.parent = KeyframeId::Make(static_cast<AgentId>(agent + 1), 7);
  kf.parent_from_cam = RandomPose(rng);
  kf.segment_from_cam = RandomPose(rng);
  return kf;
}

inline MapPointData MakeMapPointData(AgentId agent, uint64_t counter, int observations = 5) {
  std::mt19937_64 rng(counter);
  std::normal_distribution<double> n(0.0, 2.0);
  MapPointData mp;
  mp.id = MapPointId::Make(agent, counter);
  mp.segment = MapId::Make(agent, 1);
  mp.reference_kf = KeyframeId::Make(agent, 3);
  mp.position_ref = Eigen::Vector3d(n(rng), n(rng), 4.0 + n(rng));
  mp.descriptor = RandomDescriptor(rng);
  for (int i = 0; i < observations; ++i) mp.observations.emplace_back(KeyframeId::Make(agent, 3 + i), 17 * i + 2);
  return mp;
}

inline KeyframePoseUpdate MakeKeyframePoseUpdate(AgentId agent, uint64_t counter) {
  std::mt19937_64 rng(counter);
  KeyframePoseUpdate u;
  u.id = KeyframeId::Make(agent, counter);
  u.segment = MapId::Make(agent, 2);
  u.predecessor = KeyframeId::Make(agent, counter - 1);
  u.pred_from_cam = RandomPose(rng);
  u.parent = KeyframeId::Make(static_cast<AgentId>(agent + 3), 11);
  u.parent_from_cam = RandomPose(rng);
  return u;
}

inline MapPointPositionUpdate MakeMapPointPositionUpdate(AgentId agent, uint64_t counter) {
  return {MapPointId::Make(agent, counter), KeyframeId::Make(agent, 4), Eigen::Vector3d(-1.25, 0.5, 7.75)};
}

/// What the server shares with `agent`: `kfs` keyframes of agent+1 (alternating cameras) and
/// `points` points observed by them and by the agent's own keyframe 2.
inline ServerMapData MakeServerMapData(AgentId agent, int kfs, int features, int points, uint64_t seed = 5) {
  std::mt19937_64 rng(seed);
  const AgentId other = static_cast<AgentId>(agent + 1);
  ServerMapData data;
  data.reference_kf = KeyframeId::Make(agent, 9);
  for (int i = 0; i < kfs; ++i) {
    ServerKeyframe kf;
    kf.id = KeyframeId::Make(other, 100 + i);
    kf.stamp_ns = 1000 + i;
    kf.camera = Camera(i % 2 == 0 ? PinholeIntrinsics() : FisheyeIntrinsics());
    kf.features = RandomFeatures(rng, *kf.camera, features);
    kf.ref_from_cam = RandomPose(rng);
    data.keyframes.push_back(std::move(kf));
  }
  std::normal_distribution<double> n(0.0, 2.0);
  for (int i = 0; i < points; ++i) {
    ServerMapPoint mp;
    mp.id = MapPointId::Make(other, 5000 + i);
    mp.position_ref = Eigen::Vector3d(n(rng), n(rng), 5.0 + n(rng));
    if (kfs > 0) mp.observations.emplace_back(KeyframeId::Make(other, 100 + i % kfs), i % std::max(1, features));
    mp.observations.emplace_back(KeyframeId::Make(agent, 2), i);
    data.map_points.push_back(std::move(mp));
  }
  return data;
}

}  // namespace ccm::testing
