#include "runtime_common/synthetic_msgs.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "slam_core/common/ids.h"

namespace ccm::synthetic {
namespace {

msg::Pose RandomPose(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  double q[4] = {n(rng), n(rng), n(rng), n(rng)};
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  msg::Pose p;
  p.tx(n(rng)); p.ty(n(rng)); p.tz(n(rng));
  p.qx(q[0] / norm); p.qy(q[1] / norm); p.qz(q[2] / norm); p.qw(q[3] / norm);
  return p;
}

msg::OrbDescriptor RandomDescriptor(std::mt19937_64& rng) {
  msg::OrbDescriptor d;
  for (auto& byte : d.data()) byte = static_cast<std::uint8_t>(rng());
  return d;
}

// EuRoC's cam0 (pinhole radtan).
msg::CameraInfo EurocCamera() {
  msg::CameraInfo cam;
  cam.model(0); cam.width_px(752); cam.height_px(480);
  cam.fx(458.654f); cam.fy(457.296f); cam.cx(367.215f); cam.cy(248.375f);
  cam.distortion({-0.28340811f, 0.07395907f, 0.00019359f, 1.76187114e-05f});
  return cam;
}

void RandomFeatures(std::mt19937_64& rng, int num_features, std::vector<msg::Keypoint>* keypoints,
                    std::vector<msg::OrbDescriptor>* descriptors) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  keypoints->resize(num_features);
  descriptors->resize(num_features);
  for (int i = 0; i < num_features; ++i) {
    msg::Keypoint& k = (*keypoints)[i];
    k.x_eighth_px(static_cast<std::uint16_t>(8 * 752.0f * u(rng)));
    k.y_eighth_px(static_cast<std::uint16_t>(8 * 480.0f * u(rng)));
    k.angle_256(static_cast<std::uint8_t>(rng() & 0xFF));
    k.octave(static_cast<std::uint8_t>(rng() % 8));
    (*descriptors)[i] = RandomDescriptor(rng);
  }
}

std::uint64_t Seed(std::uint16_t agent, std::uint64_t index, std::uint64_t kind) {
  return (std::uint64_t{agent} << 48) ^ (index * 0x9E3779B97F4A7C15ull) ^ (kind << 40);
}

}  // namespace

msg::KeyframeFull MakeKeyframe(std::uint16_t agent, std::uint64_t index, int num_features, int num_associations) {
  std::mt19937_64 rng(Seed(agent, index, 1));
  msg::KeyframeFull kf;
  kf.protocol_version(msg::kProtocolVersion);
  kf.agent_id(agent);
  kf.id(KeyframeId::Make(agent, index + 1).packed());
  kf.segment_id(MapId::Make(agent, 1).packed());
  kf.stamp_ns(static_cast<long long>(index) * 100000000LL);
  kf.camera(EurocCamera());
  kf.pyramid_levels(8);
  kf.pyramid_scale_factor(1.2f);
  RandomFeatures(rng, num_features, &kf.keypoints(), &kf.descriptors());
  if (num_associations > 0 && num_features > 0) kf.own_mp_base(MapPointId::Make(agent, index * 1000 + 1).packed());
  for (int i = 0; i < num_associations && i < num_features; ++i) {
    kf.own_mp_keypoint_index().push_back(static_cast<std::uint16_t>(i));
    kf.own_mp_offsets().push_back(static_cast<std::uint32_t>(i));
  }
  kf.predecessor_id(index == 0 ? 0 : KeyframeId::Make(agent, index).packed());
  kf.pred_from_this(RandomPose(rng));
  kf.parent_id(kf.predecessor_id());
  kf.parent_from_this(RandomPose(rng));
  kf.segment_from_this(RandomPose(rng));
  kf.ref_kf_id(kf.id());
  return kf;
}

std::uint64_t KeyframeCounter(const msg::KeyframeFull& kf) { return KeyframeId(kf.id()).counter() - 1; }

msg::MapPointFull MakeMapPoint(std::uint16_t agent, std::uint64_t index, int num_observations) {
  std::mt19937_64 rng(Seed(agent, index, 2));
  std::normal_distribution<float> n(0.0f, 1.0f);
  msg::MapPointFull mp;
  mp.id(MapPointId::Make(agent, index + 1).packed());
  mp.ref_kf_id(KeyframeId::Make(agent, index / 100 + 1).packed());
  mp.x_ref(n(rng)); mp.y_ref(n(rng)); mp.z_ref(3.0f + n(rng));
  for (int i = 0; i < num_observations; ++i) {
    mp.obs_kf_offsets().push_back(i);
    mp.obs_keypoint_index().push_back(static_cast<std::uint16_t>(rng() % 1000));
  }
  return mp;
}

msg::KeyframeUpdate MakeKeyframeUpdate(std::uint16_t agent, std::uint64_t index) {
  std::mt19937_64 rng(Seed(agent, index, 3));
  msg::KeyframeUpdate u;
  u.protocol_version(msg::kProtocolVersion);
  u.agent_id(agent);
  u.segment_counter(1);
  u.id(KeyframeId::Make(agent, index + 1).packed());
  u.predecessor_id(KeyframeId::Make(agent, index).packed());
  u.parent_id(KeyframeId::Make(agent, index).packed());
  u.pred_from_this(RandomPose(rng));
  u.parent_from_this(RandomPose(rng));
  return u;
}

msg::MapPointUpdate MakeMapPointUpdate(std::uint16_t agent, std::uint64_t index) {
  std::mt19937_64 rng(Seed(agent, index, 4));
  std::normal_distribution<float> n(0.0f, 1.0f);
  msg::MapPointUpdate u;
  u.id(MapPointId::Make(agent, index + 1).packed());
  u.ref_kf_id(KeyframeId::Make(agent, index / 100 + 1).packed());
  u.x_ref(n(rng)); u.y_ref(n(rng)); u.z_ref(n(rng));
  return u;
}

msg::AgentStatus MakeAgentStatus(std::uint16_t agent, std::uint64_t index) {
  msg::AgentStatus s;
  s.protocol_version(msg::kProtocolVersion);
  s.agent_id(agent);
  s.stamp_ns(static_cast<long long>(index) * 500000000LL);
  s.ref_kf_id(KeyframeId::Make(agent, index + 1).packed());
  s.map_segment_id(MapId::Make(agent, 1).packed());
  s.kfs_created(static_cast<std::uint32_t>(index));
  s.tracking_state(1);
  return s;
}

msg::ServerToAgent MakeServerToAgent(std::uint16_t agent, int num_keyframes, int features_per_kf,
                                     int num_map_points, int num_acks) {
  msg::ServerToAgent m;
  m.protocol_version(msg::kProtocolVersion);
  m.agent_id(agent);
  m.ref_kf_id(KeyframeId::Make(agent, 1).packed());
  m.server_epoch(1);
  m.ack_seq(num_acks > 0 ? 1 : 0);
  for (int i = 0; i < num_acks; ++i) m.acked_kf_ids().push_back(KeyframeId::Make(agent, i + 1).packed());
  // Other agents' data, as the server shares it.
  for (int i = 0; i < num_keyframes; ++i) {
    std::mt19937_64 rng(Seed(agent + 1, i, 5));
    msg::ServerKeyframe kf;
    kf.id(KeyframeId::Make(agent + 1, i + 1).packed());
    kf.stamp_ns(static_cast<long long>(i) * 100000000LL);
    kf.camera(EurocCamera());
    RandomFeatures(rng, features_per_kf, &kf.keypoints(), &kf.descriptors());
    kf.pyramid_levels(8);
    kf.pyramid_scale_factor(1.2f);
    kf.ref_from_this(RandomPose(rng));
    m.keyframes().push_back(std::move(kf));
  }
  for (int i = 0; i < num_map_points; ++i) {
    std::mt19937_64 rng(Seed(agent + 1, i, 6));
    std::normal_distribution<float> n(0.0f, 1.0f);
    msg::ServerMapPoint mp;
    mp.id(MapPointId::Make(agent + 1, i + 1).packed());
    mp.x_ref(n(rng)); mp.y_ref(n(rng)); mp.z_ref(3.0f + n(rng));
    for (int o = 0; o < 4 && num_keyframes > 0; ++o) {
      mp.obs_kf_ids().push_back(KeyframeId::Make(agent + 1, (i + o) % num_keyframes + 1).packed());
      mp.obs_keypoint_index().push_back(static_cast<std::uint16_t>(rng() % std::max(1, features_per_kf)));
    }
    m.map_points().push_back(std::move(mp));
  }
  return m;
}

}  // namespace ccm::synthetic
