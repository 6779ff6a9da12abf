// A keyframe: immutable image measurements (keypoints, descriptors, bearings, camera)
// plus mutable estimation state (pose, map point associations, graph edges).
// Owned by a Map through shared_ptr. Any thread may call it: the mutable state has its
// own mutex (per-keyframe locking, Forster et al. 2013), held only inside each call.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

#include "slam_core/common/ids.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"

namespace ccm {

class KeyFrame {
 public:
  KeyFrame(KeyframeId id, int64_t stamp_ns, std::shared_ptr<const CameraModel> camera,
           std::shared_ptr<const FrameFeatures> features, std::shared_ptr<const ScalePyramid> pyramid,
           const SE3& world_from_cam);

  // Immutable after construction: safe to read without locks.
  KeyframeId id() const { return id_; }
  AgentId agent() const { return id_.agent(); }
  int64_t stamp_ns() const { return stamp_ns_; }
  const CameraModel& camera() const { return *camera_; }
  const std::shared_ptr<const CameraModel>& camera_ptr() const { return camera_; }
  const FrameFeatures& features() const { return *features_; }
  const std::shared_ptr<const FrameFeatures>& features_ptr() const { return features_; }
  const ScalePyramid& pyramid() const { return *pyramid_; }
  size_t num_keypoints() const { return features_->size(); }
  /// Unit bearing of keypoint i in the camera frame; zero if it could not be unprojected.
  const Eigen::Vector3d& bearing(size_t i) const { return bearings_[i]; }
  const std::vector<Eigen::Vector3d>& bearings() const { return bearings_; }

  SE3 world_from_cam() const;
  SE3 cam_from_world() const;
  Eigen::Vector3d camera_center() const;
  void SetWorldFromCam(const SE3& world_from_cam);

  /// Map point associated with keypoint i (Invalid if none). Use Map::AddObservation to
  /// create associations so both sides stay consistent.
  MapPointId MapPointAt(size_t i) const;
  std::vector<MapPointId> map_points() const;  ///< one entry per keypoint
  void SetMapPointAt(size_t i, MapPointId mp);
  /// Clears keypoint i's association if it is `mp`; returns whether it was.
  bool ClearMapPointAt(size_t i, MapPointId mp);

  // Covisibility graph (weights = number of shared map points), set by the Map.
  std::map<KeyframeId, int> covisibility() const;
  int CovisibilityWeight(KeyframeId other) const;
  /// Neighbours sorted by decreasing weight, at most `n` (all if n < 0), weight >= min_weight.
  std::vector<KeyframeId> BestCovisible(int n, int min_weight = 0) const;
  void SetCovisibility(std::map<KeyframeId, int> weights);
  void SetCovisibilityWeight(KeyframeId other, int weight);  ///< weight <= 0 removes the edge

  // Spanning tree and loop edges (essential graph), set by the Map.
  KeyframeId parent() const;
  void SetParent(KeyframeId parent);
  std::set<KeyframeId> children() const;
  void AddChild(KeyframeId child);
  void EraseChild(KeyframeId child);
  std::set<KeyframeId> loop_edges() const;
  void AddLoopEdge(KeyframeId other);

  bool bad() const;
  void SetBad();
  /// It came from the server (map sharing), also when it is one of the agent's own old
  /// keyframes sent back: the server has it, the agent never sends it. Set before the
  /// keyframe is added to a map.
  bool from_server() const { return from_server_; }
  void MarkFromServer() { from_server_ = true; }

 private:
  const KeyframeId id_;
  const int64_t stamp_ns_;
  const std::shared_ptr<const CameraModel> camera_;
  const std::shared_ptr<const FrameFeatures> features_;
  const std::shared_ptr<const ScalePyramid> pyramid_;
  std::vector<Eigen::Vector3d> bearings_;

  mutable std::mutex mutex_;
  SE3 world_from_cam_;
  std::vector<MapPointId> map_points_;
  std::map<KeyframeId, int> covisibility_;
  KeyframeId parent_;
  std::set<KeyframeId> children_;
  std::set<KeyframeId> loop_edges_;
  bool bad_ = false;
  bool from_server_ = false;
};

}  // namespace ccm
