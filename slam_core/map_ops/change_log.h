// Which keyframes and points changed since a consumer last asked: the agent's VO touches
// what it creates or optimizes, its comm module takes the set and sends it. Thread-safe.
#pragma once

#include <iterator>
#include <mutex>
#include <set>

#include "slam_core/map/map.h"

namespace ccm {

/// Keyframes and points created or changed since the comm module last asked.
class ChangeLog {
 public:
  void Touch(KeyframeId kf) {
    std::lock_guard<std::mutex> lock(mutex_);
    keyframes_.insert(kf);
  }
  void Touch(MapPointId mp) {
    std::lock_guard<std::mutex> lock(mutex_);
    map_points_.insert(mp);
  }
  void Take(std::set<KeyframeId>* kfs, std::set<MapPointId>* mps) {
    std::lock_guard<std::mutex> lock(mutex_);
    kfs->swap(keyframes_);
    mps->swap(map_points_);
    keyframes_.clear();
    map_points_.clear();
  }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return keyframes_.size() + map_points_.size();
  }
  /// Without a consumer (no server, standalone runs) the log would grow with the flight:
  /// objects that left the map will never be sent, so they are dropped.
  void Prune(const Map& map) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = keyframes_.begin(); it != keyframes_.end();) it = map.keyframe(*it) ? std::next(it) : keyframes_.erase(it);
    for (auto it = map_points_.begin(); it != map_points_.end();) {
      it = map.map_point(*it) ? std::next(it) : map_points_.erase(it);
    }
  }

 private:
  mutable std::mutex mutex_;
  std::set<KeyframeId> keyframes_;
  std::set<MapPointId> map_points_;
};

}  // namespace ccm
