#include "slam_core/place_recognition/map_adapter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

namespace ccm {

namespace {

// `kf`'s own part of a view: features, camera, pyramid and its good map points in its camera
// frame (NaN where it has none).
VerificationView OwnView(const KeyFrame& kf, const Map& map) {
  VerificationView view;
  view.camera = kf.camera_ptr();
  view.features = kf.features();
  view.pyramid = kf.pyramid();
  const SE3 cam_from_world = kf.cam_from_world();
  view.points_cam.assign(view.features.size(), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  const std::vector<MapPointId> points = kf.map_points();
  for (std::size_t i = 0; i < points.size() && i < view.points_cam.size(); ++i) {
    if (!points[i].valid()) continue;
    const std::shared_ptr<MapPoint> mp = map.map_point(points[i]);
    if (mp && !mp->bad()) view.points_cam[i] = cam_from_world * mp->position();
  }
  return view;
}

}  // namespace

VerificationView MakeVerificationView(const KeyFrame& kf, const Map& map, const Vocabulary& vocab,
                                      int levels_up, BowVector* bow) {
  VerificationView view = OwnView(kf, map);
  BowVector local;
  vocab.Transform(view.features.descriptors, bow ? bow : &local, &view.feature_vector, levels_up);
  return view;
}

KeypointNodesFn VocabularyNodes(const Vocabulary& vocab, int levels_up) {
  return [&vocab, levels_up](const KeyFrame& kf) {
    const int level = std::max(1, vocab.levels() - levels_up);
    const auto& descriptors = kf.features().descriptors;
    std::vector<NodeId> nodes(descriptors.size(), kNoNode);
    if (vocab.empty()) return nodes;
    for (std::size_t i = 0; i < descriptors.size(); ++i) vocab.Transform(descriptors[i], &nodes[i], level);
    return nodes;
  };
}

VerificationView MakeWindowView(const KeyFrame& kf, const std::vector<std::shared_ptr<KeyFrame>>& neighbours,
                                const Map& map, const KeypointNodesFn& nodes, size_t* real_keypoints) {
  VerificationView view = OwnView(kf, map);
  *real_keypoints = view.features.size();
  const SE3 cam_from_world = kf.cam_from_world();
  std::vector<NodeId> node_of = nodes(kf);
  node_of.resize(view.features.size(), kNoNode);
  // Every point kf sees, good or not, is its own: only the others' are added.
  std::unordered_set<MapPointId> seen;
  for (const MapPointId id : kf.map_points()) {
    if (id.valid()) seen.insert(id);
  }
  const double log_sf = std::log(view.pyramid.scale_factor);
  for (const auto& n : neighbours) {
    if (!n || n->id() == kf.id()) continue;
    const SE3 n_from_world = n->cam_from_world();
    const std::vector<MapPointId> points = n->map_points();
    const FrameFeatures& nf = n->features();
    const std::vector<NodeId> n_nodes = nodes(*n);
    for (std::size_t i = 0; i < points.size() && i < nf.size(); ++i) {
      if (!points[i].valid() || !seen.insert(points[i]).second) continue;
      const std::shared_ptr<MapPoint> mp = map.map_point(points[i]);
      if (!mp || mp->bad()) continue;
      const Eigen::Vector3d p = cam_from_world * mp->position();
      Eigen::Vector2d uv;
      if (p.z() <= 0.0 || !view.camera->Project(p, &uv) || !view.camera->InImage(uv)) continue;
      // Nearer than in the neighbour: the point looks bigger, a coarser pyramid level.
      const double ratio = (n_from_world * mp->position()).norm() / p.norm();
      Keypoint k = nf.keypoints[i];
      k.u = static_cast<float>(uv.x());
      k.v = static_cast<float>(uv.y());
      k.level = std::clamp(static_cast<int>(std::lround(k.level + std::log(ratio) / log_sf)), 0,
                           view.pyramid.num_levels - 1);
      view.features.keypoints.push_back(k);
      view.features.descriptors.push_back(nf.descriptors[i]);
      view.points_cam.push_back(p);
      node_of.push_back(i < n_nodes.size() ? n_nodes[i] : kNoNode);
    }
  }
  view.feature_vector = FeatureVectorOf(node_of);
  return view;
}

CovisibilityFn MapCovisibility(const Map& map) {
  return [&map](KeyframeId id, int n) -> std::vector<KeyframeId> {
    const std::shared_ptr<KeyFrame> kf = map.keyframe(id);
    if (!kf) return {};
    return kf->BestCovisible(n);
  };
}

}  // namespace ccm
