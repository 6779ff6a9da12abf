// Smooth drone-like camera trajectories: a C2 natural cubic spline through waypoints,
// flown at a smoothly varying speed, camera yawed along the direction of travel plus a
// per-waypoint yaw offset, pitched down, with a small roll/pitch wobble.
// Use: Trajectory::Create(spec) once per agent, then WorldFromCam(t) for any time.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slam_core/geometry/se3.h"

namespace ccm::sim {

struct Waypoint {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  double yaw_offset_deg = 0.0;  ///< camera yaw relative to the direction of travel (+ = left)
};

struct TrajectorySpec {
  std::vector<Waypoint> waypoints;
  bool loop = true;              ///< closed path flown repeatedly (revisits => loop closures)
  double duration_s = 60.0;      ///< flight time
  double min_speed_mps = 0.4;    ///< speed oscillates smoothly between min and max
  double max_speed_mps = 1.2;
  double speed_period_s = 17.0;  ///< period of the speed oscillation
  double pitch_deg = -12.0;      ///< camera pitch (negative looks down)
  double wobble_deg = 1.5;       ///< amplitude of the roll and pitch wobble
  double look_ahead_m = 1.0;     ///< heading from the path +- this arc length (smooths yaw)
  std::string Validate() const;  ///< empty if usable
};

/// Immutable, thread-safe after Create().
class Trajectory {
 public:
  /// nullptr + *error if the spec is invalid or the path is too short for the duration.
  static std::unique_ptr<Trajectory> Create(const TrajectorySpec& spec, std::string* error);

  SE3 WorldFromCam(double t_s) const;
  Eigen::Vector3d Position(double t_s) const;
  /// Velocity of the camera centre in the world frame [m/s] (central difference).
  Eigen::Vector3d Velocity(double t_s) const;
  /// Arc length flown at time t [m].
  double ArcLength(double t_s) const;
  double duration_s() const { return spec_.duration_s; }
  double path_length_m() const { return arc_.back(); }
  const TrajectorySpec& spec() const { return spec_; }

 private:
  explicit Trajectory(const TrajectorySpec& spec) : spec_(spec) {}
  void Build(const std::vector<Waypoint>& points);
  // Spline value (x, y, z, yaw_offset_rad) at arc length s.
  Eigen::Vector4d AtArc(double s) const;
  Eigen::Vector4d AtKnotParam(double tau) const;

  TrajectorySpec spec_;
  std::vector<double> knots_;                 // chord-length parameter per control point
  std::vector<Eigen::Vector4d> values_, second_;  // spline values and second derivatives
  std::vector<double> arc_tau_, arc_;         // arc-length table: tau -> s
};

}  // namespace ccm::sim
