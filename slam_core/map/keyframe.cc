#include "slam_core/map/keyframe.h"

#include <algorithm>

namespace ccm {

KeyFrame::KeyFrame(KeyframeId id, int64_t stamp_ns, std::shared_ptr<const CameraModel> camera,
                   std::shared_ptr<const FrameFeatures> features, std::shared_ptr<const ScalePyramid> pyramid,
                   const SE3& world_from_cam)
    : id_(id),
      stamp_ns_(stamp_ns),
      camera_(std::move(camera)),
      features_(std::move(features)),
      pyramid_(std::move(pyramid)),
      world_from_cam_(world_from_cam),
      map_points_(features_->size()) {
  bearings_.resize(features_->size(), Eigen::Vector3d::Zero());
  for (size_t i = 0; i < features_->size(); ++i) {
    const Keypoint& kp = features_->keypoints[i];
    Eigen::Vector3d b;
    if (camera_->Unproject(Eigen::Vector2d(kp.u, kp.v), &b)) bearings_[i] = b;
  }
}

SE3 KeyFrame::world_from_cam() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return world_from_cam_;
}
SE3 KeyFrame::cam_from_world() const { return world_from_cam().inverse(); }
Eigen::Vector3d KeyFrame::camera_center() const { return world_from_cam().translation(); }
void KeyFrame::SetWorldFromCam(const SE3& world_from_cam) {
  std::lock_guard<std::mutex> lock(mutex_);
  world_from_cam_ = world_from_cam;
}

MapPointId KeyFrame::MapPointAt(size_t i) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return i < map_points_.size() ? map_points_[i] : MapPointId::Invalid();
}
std::vector<MapPointId> KeyFrame::map_points() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return map_points_;
}
void KeyFrame::SetMapPointAt(size_t i, MapPointId mp) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (i < map_points_.size()) map_points_[i] = mp;
}
bool KeyFrame::ClearMapPointAt(size_t i, MapPointId mp) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (i >= map_points_.size() || map_points_[i] != mp) return false;
  map_points_[i] = MapPointId::Invalid();
  return true;
}

std::map<KeyframeId, int> KeyFrame::covisibility() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return covisibility_;
}
int KeyFrame::CovisibilityWeight(KeyframeId other) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = covisibility_.find(other);
  return it == covisibility_.end() ? 0 : it->second;
}
std::vector<KeyframeId> KeyFrame::BestCovisible(int n, int min_weight) const {
  std::vector<std::pair<int, KeyframeId>> sorted;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [kf, w] : covisibility_) {
      if (w >= min_weight) sorted.emplace_back(w, kf);
    }
  }
  // Ties broken by id so the order is deterministic.
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  std::vector<KeyframeId> out;
  for (const auto& [w, kf] : sorted) {
    if (n >= 0 && static_cast<int>(out.size()) >= n) break;
    out.push_back(kf);
  }
  return out;
}
void KeyFrame::SetCovisibility(std::map<KeyframeId, int> weights) {
  std::lock_guard<std::mutex> lock(mutex_);
  covisibility_ = std::move(weights);
}
void KeyFrame::SetCovisibilityWeight(KeyframeId other, int weight) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (weight <= 0) {
    covisibility_.erase(other);
  } else {
    covisibility_[other] = weight;
  }
}

KeyframeId KeyFrame::parent() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return parent_;
}
void KeyFrame::SetParent(KeyframeId parent) {
  std::lock_guard<std::mutex> lock(mutex_);
  parent_ = parent;
}
std::set<KeyframeId> KeyFrame::children() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return children_;
}
void KeyFrame::AddChild(KeyframeId child) {
  std::lock_guard<std::mutex> lock(mutex_);
  children_.insert(child);
}
void KeyFrame::EraseChild(KeyframeId child) {
  std::lock_guard<std::mutex> lock(mutex_);
  children_.erase(child);
}
std::set<KeyframeId> KeyFrame::loop_edges() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return loop_edges_;
}
void KeyFrame::AddLoopEdge(KeyframeId other) {
  std::lock_guard<std::mutex> lock(mutex_);
  loop_edges_.insert(other);
}

bool KeyFrame::bad() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bad_;
}
void KeyFrame::SetBad() {
  std::lock_guard<std::mutex> lock(mutex_);
  bad_ = true;
}

}  // namespace ccm
