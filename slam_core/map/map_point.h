// A 3D landmark of a map: position, observations (keyframe id -> keypoint index) and
// the view geometry used to predict its appearance (descriptor, normal, depth range).
// Owned by a Map through shared_ptr; any thread may call it (own mutex, short sections).
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "slam_core/common/ids.h"
#include "slam_core/feature/orb_types.h"

namespace ccm {

class MapPoint {
 public:
  MapPoint(MapPointId id, const Eigen::Vector3d& position_world, KeyframeId reference_kf,
           const OrbDescriptor& descriptor);

  MapPointId id() const { return id_; }

  Eigen::Vector3d position() const;
  void SetPosition(const Eigen::Vector3d& position_world);
  KeyframeId reference_kf() const;
  void SetReferenceKf(KeyframeId kf);

  /// Snapshot of (keyframe, keypoint index) pairs, sorted by keyframe id.
  std::vector<std::pair<KeyframeId, int>> observations() const;
  /// The same, and a stamp that changes whenever an observation is added or erased.
  std::vector<std::pair<KeyframeId, int>> observations(std::uint64_t* stamp) const;
  int num_observations() const;
  std::optional<int> KeypointIn(KeyframeId kf) const;
  /// The Map keeps both sides consistent: call Map::AddObservation, not these.
  bool AddObservation(KeyframeId kf, int keypoint_index);
  bool EraseObservation(KeyframeId kf);

  OrbDescriptor descriptor() const;
  Eigen::Vector3d normal() const;
  double min_distance_m() const;
  double max_distance_m() const;
  /// Set by Map::UpdateMapPointAppearance from the observing keyframes. `basis` names what
  /// the descriptor was computed from (Map's fingerprint of the observations), so that an
  /// update after the point only moved can keep it; kNoBasis: unknown (recomputed next time).
  static constexpr std::uint64_t kNoBasis = ~std::uint64_t{0};
  void SetAppearance(const OrbDescriptor& descriptor, const Eigen::Vector3d& normal, double min_distance_m,
                     double max_distance_m, std::uint64_t basis = kNoBasis);
  /// Whether the descriptor was computed from observations with this fingerprint.
  bool DescriptorBasedOn(std::uint64_t basis) const;
  /// Pyramid level at which the point should appear at this distance (ORB-SLAM rule).
  int PredictLevel(double distance_m, const ScalePyramid& pyramid) const;

  /// It came from the server (map sharing): see KeyFrame::from_server(). Set before the
  /// point is added to a map.
  bool from_server() const { return from_server_; }
  void MarkFromServer() { from_server_ = true; }
  bool bad() const;
  void SetBad(MapPointId replaced_by = MapPointId::Invalid());
  MapPointId replaced_by() const;

  /// Tracking statistics: how often the point was predicted visible vs. actually matched.
  void IncreaseVisible(int n = 1);
  void IncreaseFound(int n = 1);
  double found_ratio() const;

 private:
  const MapPointId id_;
  mutable std::mutex mutex_;
  Eigen::Vector3d position_world_;
  KeyframeId reference_kf_;
  std::vector<std::pair<KeyframeId, int>> observations_;  // sorted by id
  std::uint64_t observations_stamp_ = 0;                   // +1 per change of observations_
  OrbDescriptor descriptor_;
  std::uint64_t descriptor_basis_ = kNoBasis;
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  double min_distance_m_ = 0.0, max_distance_m_ = 0.0;
  bool bad_ = false;
  bool from_server_ = false;
  MapPointId replaced_by_;
  int visible_ = 1, found_ = 1;
};

}  // namespace ccm
