// Keyframe snapshots from the simulator for place-recognition tests and the benchmark:
// rendered image -> ORB -> bag of words + direct index, and "map points" from exact ray casts
// made SLAM-like (a fraction of keypoints only, depth noise, a per-map scale).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "slam_core/feature/orb_extractor.h"
#include "slam_core/geometry/se3.h"
#include "slam_core/place_recognition/geometric_verification.h"
#include "slam_core/place_recognition/vocabulary.h"
#include "tests/sim/simulation.h"

namespace ccm::test {

struct SimKeyframe {
  int scene = 0;            ///< keyframes of different scenes never show the same place
  int agent = 0;
  std::int64_t index = 0;   ///< frame index of the agent
  double time_s = 0.0;
  SE3 world_from_cam;       ///< ground truth
  double map_scale = 1.0;   ///< points_cam = map_scale * metric points
  BowVector bow;
  VerificationView view;
};

struct SimKeyframeOptions {
  std::int64_t stride = 16;          ///< every stride-th frame ...
  std::int64_t offset = 0;           ///< ... starting here
  int max_keyframes = -1;            ///< at most this many (-1 = all)
  int num_features = 1000;
  double point_fraction = 0.6;       ///< keypoints that get a map point
  double depth_noise = 0.01;         ///< relative depth noise (1 sigma)
  double map_scale = 1.0;
  int levels_up = -1;                ///< direct index level = L - levels_up; -1: depth 2 (ORB-SLAM's)
  std::uint64_t seed = 1;
};

/// Keyframes of one agent of `sim`.
std::vector<SimKeyframe> MakeSimKeyframes(const sim::Simulation& sim, int agent,
                                          const Vocabulary& vocab, const SimKeyframeOptions& options);

/// True if the two ground-truth poses see the same place: camera centres closer than
/// max_dist_m and optical axes within max_angle_deg.
bool SamePlace(const SE3& a, const SE3& b, double max_dist_m, double max_angle_deg);

/// Ground-truth query_from_candidate Sim(3) between two keyframes' map frames.
Sim3 TrueQueryFromCandidate(const SimKeyframe& candidate, const SimKeyframe& query);

/// Translation (metric, divided by the query's map scale) and rotation errors of an estimate.
void Sim3Error(const Sim3& estimate, const Sim3& truth, double query_scale, double* trans_m,
               double* rot_deg);

/// The default vocabulary (build-tree file from CMake, trained here with the same spec if
/// missing; tools/vocab/default_vocabulary.h).
const Vocabulary& DefaultVocabulary();

}  // namespace ccm::test
