#include "slam_core/place_recognition/map_adapter.h"

#include <limits>

namespace ccm {

VerificationView MakeVerificationView(const KeyFrame& kf, const Map& map, const Vocabulary& vocab,
                                      int levels_up, BowVector* bow) {
  VerificationView view;
  view.camera = kf.camera_ptr();
  view.features = kf.features();
  view.pyramid = kf.pyramid();
  const SE3 cam_from_world = kf.cam_from_world();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  view.points_cam.assign(view.features.size(), Eigen::Vector3d::Constant(nan));
  const std::vector<MapPointId> points = kf.map_points();
  for (std::size_t i = 0; i < points.size() && i < view.points_cam.size(); ++i) {
    if (!points[i].valid()) continue;
    const std::shared_ptr<MapPoint> mp = map.map_point(points[i]);
    if (mp && !mp->bad()) view.points_cam[i] = cam_from_world * mp->position();
  }
  BowVector local;
  vocab.Transform(view.features.descriptors, bow ? bow : &local, &view.feature_vector, levels_up);
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
