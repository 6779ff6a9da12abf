#include "slam_core/map/map_point.h"

#include <algorithm>
#include <cmath>

namespace ccm {

MapPoint::MapPoint(MapPointId id, const Eigen::Vector3d& position_world, KeyframeId reference_kf,
                   const OrbDescriptor& descriptor)
    : id_(id), position_world_(position_world), reference_kf_(reference_kf), descriptor_(descriptor) {}

Eigen::Vector3d MapPoint::position() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return position_world_;
}
void MapPoint::SetPosition(const Eigen::Vector3d& p) {
  std::lock_guard<std::mutex> lock(mutex_);
  position_world_ = p;
}
KeyframeId MapPoint::reference_kf() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reference_kf_;
}
void MapPoint::SetReferenceKf(KeyframeId kf) {
  std::lock_guard<std::mutex> lock(mutex_);
  reference_kf_ = kf;
}

std::vector<std::pair<KeyframeId, int>> MapPoint::observations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return observations_;
}
std::vector<std::pair<KeyframeId, int>> MapPoint::observations(std::uint64_t* stamp) const {
  std::lock_guard<std::mutex> lock(mutex_);
  *stamp = observations_stamp_;
  return observations_;
}
int MapPoint::num_observations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(observations_.size());
}

namespace {
auto FindObs(std::vector<std::pair<KeyframeId, int>>& obs, KeyframeId kf) {
  return std::lower_bound(obs.begin(), obs.end(), kf, [](const auto& o, KeyframeId k) { return o.first < k; });
}
}  // namespace

std::optional<int> MapPoint::KeypointIn(KeyframeId kf) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto& obs = const_cast<std::vector<std::pair<KeyframeId, int>>&>(observations_);
  const auto it = FindObs(obs, kf);
  if (it == obs.end() || it->first != kf) return std::nullopt;
  return it->second;
}

bool MapPoint::AddObservation(KeyframeId kf, int keypoint_index) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = FindObs(observations_, kf);
  if (it != observations_.end() && it->first == kf) return false;
  observations_.insert(it, {kf, keypoint_index});
  ++observations_stamp_;
  return true;
}

bool MapPoint::EraseObservation(KeyframeId kf) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = FindObs(observations_, kf);
  if (it == observations_.end() || it->first != kf) return false;
  observations_.erase(it);
  ++observations_stamp_;
  return true;
}

OrbDescriptor MapPoint::descriptor() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return descriptor_;
}
Eigen::Vector3d MapPoint::normal() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return normal_;
}
double MapPoint::min_distance_m() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return min_distance_m_;
}
double MapPoint::max_distance_m() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return max_distance_m_;
}
void MapPoint::SetAppearance(const OrbDescriptor& descriptor, const Eigen::Vector3d& normal, double min_distance_m,
                             double max_distance_m, std::uint64_t basis) {
  std::lock_guard<std::mutex> lock(mutex_);
  descriptor_ = descriptor;
  descriptor_basis_ = basis;
  normal_ = normal;
  min_distance_m_ = min_distance_m;
  max_distance_m_ = max_distance_m;
}

bool MapPoint::DescriptorBasedOn(std::uint64_t basis) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return basis != kNoBasis && descriptor_basis_ == basis;
}

int MapPoint::PredictLevel(double distance_m, const ScalePyramid& pyramid) const {
  double ratio;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ratio = max_distance_m_ / std::max(distance_m, 1e-9);
  }
  // max_distance corresponds to level 0 seen from afar; closer means a higher level.
  const int level = static_cast<int>(std::ceil(std::log(ratio) / std::log(pyramid.scale_factor)));
  return std::clamp(level, 0, pyramid.num_levels - 1);
}

bool MapPoint::bad() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bad_;
}
void MapPoint::SetBad(MapPointId replaced_by) {
  std::lock_guard<std::mutex> lock(mutex_);
  bad_ = true;
  replaced_by_ = replaced_by;
}
MapPointId MapPoint::replaced_by() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return replaced_by_;
}

void MapPoint::IncreaseVisible(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  visible_ += n;
}
void MapPoint::IncreaseFound(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  found_ += n;
}
double MapPoint::found_ratio() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<double>(found_) / std::max(visible_, 1);
}

}  // namespace ccm
