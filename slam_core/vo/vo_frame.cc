#include "slam_core/vo/vo_frame.h"

namespace ccm {

int VoFrame::NumMatched() const {
  int n = 0;
  for (size_t i = 0; i < map_points.size(); ++i) n += map_points[i] && !outlier[i];
  return n;
}

void VoFrame::DiscardOutliers() {
  for (size_t i = 0; i < map_points.size(); ++i) {
    if (outlier[i]) {
      map_points[i] = nullptr;
      outlier[i] = false;
    }
  }
}

VoFrame MakeVoFrame(int64_t stamp_ns, int64_t index, FrameFeatures features, const CameraModel& camera) {
  VoFrame f;
  f.stamp_ns = stamp_ns;
  f.index = index;
  auto shared = std::make_shared<FrameFeatures>(std::move(features));
  f.bearings.assign(shared->size(), Eigen::Vector3d::Zero());
  for (size_t i = 0; i < shared->size(); ++i) {
    const Keypoint& kp = shared->keypoints[i];
    Eigen::Vector3d b;
    if (camera.Unproject(Eigen::Vector2d(kp.u, kp.v), &b)) f.bearings[i] = b;
  }
  f.grid = std::make_shared<KeypointGrid>(*shared, camera.width(), camera.height());
  f.map_points.assign(shared->size(), nullptr);
  f.outlier.assign(shared->size(), false);
  f.features = std::move(shared);
  return f;
}

}  // namespace ccm
