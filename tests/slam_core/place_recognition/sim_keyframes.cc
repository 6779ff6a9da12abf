#include "tests/slam_core/place_recognition/sim_keyframes.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <stdexcept>

#include "tools/vocab/default_vocabulary.h"

namespace ccm::test {

std::vector<SimKeyframe> MakeSimKeyframes(const sim::Simulation& sim, int agent,
                                          const Vocabulary& vocab, const SimKeyframeOptions& options) {
  OrbExtractorOptions orb;
  orb.num_features = options.num_features;
  OrbExtractor extractor(orb);
  std::shared_ptr<const CameraModel> camera = MakeCamera(sim.scenario().camera);
  std::mt19937_64 rng(options.seed * 1000003u + static_cast<std::uint64_t>(agent));
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<SimKeyframe> out;
  for (std::int64_t i = options.offset; i < sim.NumFrames(agent); i += options.stride) {
    if (options.max_keyframes >= 0 && static_cast<int>(out.size()) >= options.max_keyframes) break;
    SimKeyframe kf;
    kf.agent = agent;
    kf.index = i;
    kf.time_s = sim.TimeS(agent, i);
    kf.world_from_cam = sim.WorldFromCam(agent, i);
    kf.map_scale = options.map_scale;
    kf.view.camera = camera;
    kf.view.pyramid = extractor.pyramid();
    kf.view.features = extractor.Extract(sim.RenderFrame(agent, i));
    const int levels_up = options.levels_up >= 0 ? options.levels_up : std::max(0, vocab.levels() - 2);
    vocab.Transform(kf.view.features.descriptors, &kf.bow, &kf.view.feature_vector, levels_up);
    const SE3 cam_from_world = kf.world_from_cam.inverse();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    kf.view.points_cam.assign(kf.view.features.size(), Eigen::Vector3d::Constant(nan));
    for (std::size_t k = 0; k < kf.view.features.size(); ++k) {
      if (uniform(rng) >= options.point_fraction) continue;
      const auto& kp = kf.view.features.keypoints[k];
      const auto hit = sim.renderer().CastRay(kf.world_from_cam, Eigen::Vector2d(kp.u, kp.v));
      if (!hit) continue;
      const Eigen::Vector3d p = cam_from_world * hit->point_w;
      kf.view.points_cam[k] = options.map_scale * p * (1.0 + options.depth_noise * normal(rng));
    }
    out.push_back(std::move(kf));
  }
  return out;
}

bool SamePlace(const SE3& a, const SE3& b, double max_dist_m, double max_angle_deg) {
  if ((a.translation() - b.translation()).norm() > max_dist_m) return false;
  const Eigen::Vector3d za = a.rotation() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d zb = b.rotation() * Eigen::Vector3d::UnitZ();
  return za.dot(zb) >= std::cos(max_angle_deg * M_PI / 180.0);
}

Sim3 TrueQueryFromCandidate(const SimKeyframe& candidate, const SimKeyframe& query) {
  const SE3 q_from_c = query.world_from_cam.inverse() * candidate.world_from_cam;
  // p_q_map = s_q * (R p_c_metric + t), p_c_metric = p_c_map / s_c.
  return Sim3(query.map_scale / candidate.map_scale, q_from_c.rotation(),
              query.map_scale * q_from_c.translation());
}

void Sim3Error(const Sim3& estimate, const Sim3& truth, double query_scale, double* trans_m,
               double* rot_deg) {
  *trans_m = (estimate.translation() - truth.translation()).norm() / query_scale;
  *rot_deg = estimate.rotation().angularDistance(truth.rotation()) * 180.0 / M_PI;
}

const Vocabulary& DefaultVocabulary() {
  static const Vocabulary vocab = [] {
    std::string error;
    auto v = vocab::LoadOrTrainDefaultVocabulary(
        CCM_DEFAULT_VOCAB_FILE, vocab::MakeDefaultVocabularySpec(), &error);
    if (!v) throw std::runtime_error("default vocabulary: " + error);
    return std::move(*v);
  }();
  return vocab;
}

}  // namespace ccm::test
