// Which agents of a simulated scenario saw the same place, and when: exact, from the
// simulator's ground truth. Each agent's views are sampled a few times a second; a view is
// a grid of rays cast into the world, each landing in a 0.5 m cell of a surface. Two views
// are co-visible when each has at least `min_shared` of its rays in cells the other view
// saw from a compatible viewpoint (ray directions within `max_ray_angle_deg`, ranges within
// a factor `max_range_ratio`): what a feature matcher could match, not merely the same wall
// from across a hall. Per pair of agents this gives the first moment both had seen a common
// place, how long each looked at it and from what angle; per agent, whether it revisits its
// own path. Used by bench_fusion and the server tests to score recall and precision.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "slam_core/geometry/se3.h"
#include "tests/sim/simulation.h"

namespace ccm::sim {

struct OverlapTruthOptions {
  double sample_hz = 4.0;          ///< views per second of flight
  int grid_cols = 24, grid_rows = 16;
  double cell_m = 0.5;             ///< surface cell size
  double min_shared = 0.25;        ///< share of each view's rays that the other view saw
  double max_ray_angle_deg = 60.0; ///< median angle between the two views' rays to shared cells
  double max_range_ratio = 2.5;    ///< median range ratio of shared cells
  double qualify_angle_deg = 45.0; ///< overlaps that count: views at most this far apart ...
  double qualify_seconds = 3.0;    ///< ... for at least this long (each agent)
  double revisit_gap_s = 15.0;     ///< own views this far apart in time make a revisit
};

/// One sampled view: cells hit (sorted), with the ray direction and range of the first ray
/// into each, and how many rays landed there.
struct SampledView {
  double time_s = 0.0;
  SE3 world_from_cam;
  int rays = 0;                        ///< rays that hit something
  std::vector<std::uint64_t> cells;    ///< sorted
  std::vector<Eigen::Vector3f> dirs;   ///< unit, world frame, per cell
  std::vector<float> ranges;           ///< per cell [m]
  std::vector<int> counts;             ///< rays per cell
};

/// Co-visibility of two views; angle_deg is the median ray angle over shared cells.
struct ViewOverlap {
  bool covisible = false;
  double share_a = 0.0, share_b = 0.0, angle_deg = 0.0;
};

struct PairTruth {
  int a = 0, b = 0;                 ///< agent indices, a < b
  bool overlaps = false;            ///< any co-visible pair of views
  bool qualifies = false;           ///< >= qualify_seconds each within qualify_angle_deg
  double first_s = -1.0;            ///< earliest max(t_a, t_b) of a qualifying-angle co-visible pair
  double seconds_a = 0.0, seconds_b = 0.0;  ///< time each looked at the common place (<= qualify angle)
  double median_angle_deg = 0.0;    ///< over all co-visible view pairs
  std::string kind;                 ///< measured: none, brief (< 3 s), same (<= 25 deg), oblique
};

struct AgentTruth {
  bool revisits = false;            ///< own views >= revisit_gap_s apart co-visible for >= 2 s
  double first_revisit_s = -1.0;
  double path_m = 0.0;
};

class OverlapTruth {
 public:
  /// Samples every agent's flight and compares every pair of views (a few seconds).
  static OverlapTruth Compute(const Simulation& sim, const OverlapTruthOptions& options = {});

  const std::vector<PairTruth>& pairs() const { return pairs_; }
  const std::vector<AgentTruth>& agents() const { return agents_; }
  const OverlapTruthOptions& options() const { return options_; }
  const PairTruth& pair(int a, int b) const;
  /// Samples one view of the simulation's world (e.g. a keyframe's ground-truth pose).
  SampledView Sample(const Simulation& sim, const SE3& world_from_cam, double time_s) const;
  ViewOverlap Compare(const SampledView& a, const SampledView& b) const;
  /// The same with other limits on the rays to a shared cell.
  ViewOverlap Compare(const SampledView& a, const SampledView& b, double max_ray_angle_deg, double max_range_ratio) const;
  /// Whether two views can have seen the same surface at all: any shared cell under lenient
  /// ray limits (a point can be matched across 90 deg and 10x range; far walls in a yard
  /// are). False means map points both views share are wrong associations.
  bool MayShareSurface(const SampledView& a, const SampledView& b) const;

 private:
  OverlapTruthOptions options_;
  std::vector<std::vector<SampledView>> views_;  // per agent
  std::vector<PairTruth> pairs_;
  std::vector<AgentTruth> agents_;
};

}  // namespace ccm::sim
