// The scene generator's workbench (scene_generator.h is the interface): the layout of one
// generated scene (space, cells, objects) and the agents' flight plans in it. Objects are
// kept as YAML lines plus footprints, so flights and objects can be checked against each
// other (no flight through a crate, no crate on a flight path).
// Order of use: NeighbourPairs -> PlanSharedTarget per overlapping pair -> BuildFlights ->
// AddFillerObjects. Not thread-safe; one per generated scene.
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "tests/sim/scene_generator.h"
#include "tests/sim/sim_random.h"
#include "tests/sim/trajectory.h"

namespace ccm::sim {

/// Degrees to radians (scene layouts and flights are written in degrees).
inline constexpr double kDeg = M_PI / 180.0;

struct FlightWaypoint {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  double yaw_deg = 0.0;  ///< camera yaw offset from the direction of travel
  /// Where the camera must look here (the yaw offset follows from the flown heading):
  /// kFree keeps yaw_deg, kLookAt faces `view` (a point), kLookAlong faces direction `view`.
  enum class View { kFree, kLookAt, kLookAlong } mode = View::kFree;
  Eigen::Vector2d view = Eigen::Vector2d::Zero();
};

struct FlightPlan {
  std::vector<FlightWaypoint> waypoints;  ///< a closed loop
  double min_speed = 0.5, max_speed = 1.0, speed_period = 15.0;
  double pitch_deg = -12.0, wobble_deg = 1.5;
  double look_ahead_m = 1.5;  ///< heading from the path +- this (a steadier heading through bends)
  double duration_s = 40.0;
};

/// Texture style of an object in a scene of `profile` (0 rich, 1 mixed, 2 weak).
const char* ObjectStyleForProfile(Rng* rng, int profile);

class SceneBuilder {
 public:
  /// profile: 0 rich, 1 mixed, 2 weak textures.
  SceneBuilder(SceneLayout layout, int agents, int profile, Rng* rng);

  /// Pairs of agents in neighbouring cells (a < b).
  std::vector<std::pair<int, int>> NeighbourPairs() const;
  /// Puts a target object between the two agents' cells and a viewing arc for each of them
  /// (angle and duration by p->kind); fills p->view_angle_deg and p->seconds.
  void PlanSharedTarget(PlannedOverlap* p);
  /// Every agent's loop (its cell loop with its arcs), speeds fitted so that it flies the
  /// loop 1.3-2.5 times in about `duration_s`.
  void BuildFlights(double duration_s);
  /// Crates, pillars, shelves, posters (containers, cars, posts in a yard) off the flight paths.
  void AddFillerObjects();

  const std::vector<std::string>& objects_yaml() const { return objects_; }
  const FlightPlan& flight(int agent) const { return agents_.at(agent).flight; }
  /// False when the agent's loop could not join its shared arcs smoothly and flies without.
  bool arcs_flown(int agent) const { return !agents_.at(agent).arcs_dropped; }
  double texel_m() const { return texel_m_; }
  double background_grey() const { return background_grey_; }
  double duration_s() const { return duration_s_; }

 private:
  struct Obstacle {
    Eigen::Vector2d center, half;  // footprint: rectangle of half sizes, yawed
    double yaw_rad = 0.0, top = 0.0;
    bool Contains(const Eigen::Vector2d& p, double margin) const;
  };
  // Where two agents see the same place: an orbit round a target, camera on the target, or
  // a straight run beside a partition or wall, camera looking along a fixed direction.
  struct ViewArc {
    bool run = false;
    Eigen::Vector2d target = Eigen::Vector2d::Zero();     // orbit centre
    Eigen::Vector2d direction = Eigen::Vector2d::UnitX(); // orbit: unit, target -> middle of the arc
    double radius = 2.5;
    Eigen::Vector2d run_middle = Eigen::Vector2d::Zero(), run_dir = Eigen::Vector2d::UnitX();  // run: line
    Eigen::Vector2d view_dir = Eigen::Vector2d::UnitY();  // run: camera direction
    double seconds = 5.0;                                 // planned flight time along it
  };
  struct AgentPlan {
    Eigen::Vector2d cell_center, center;
    double rx = 2.0, ry = 2.0, altitude = 1.5;
    int dir = 1;                 // +1 counter-clockwise
    int yaw_style = 0;           // 0 forward, 1 sideways, 2 varying
    double yaw_base = 0.0;
    std::vector<ViewArc> arcs;
    bool arcs_dropped = false;
    FlightPlan flight;
  };

  void MakeSpace();
  void MakeAgents();
  std::vector<FlightWaypoint> ArcPoints(const AgentPlan& a, const ViewArc& arc, double mean_speed) const;
  std::vector<FlightWaypoint> LoopWaypoints(AgentPlan* a, double mean_speed, bool plain);
  void FitSpeeds(AgentPlan* a, double duration_s);
  void KeepClear(std::vector<FlightWaypoint>* wps) const;
  TrajectorySpec Spec(const FlightPlan& f) const;
  /// Finds the first place where the flown spline meets a wall or an obstacle and inserts a
  /// waypoint that goes round it (or, with `climb`, lifts the leg over it); false when the
  /// flight is clear.
  bool DetourOnce(FlightPlan* f, bool climb) const;
  bool InSpace(const Eigen::Vector2d& p, double margin) const;
  bool Blocks(const Obstacle& o, double margin) const;  // o hits a flight path or another obstacle
  void AddBox(const std::string& type, const std::string& name, const Eigen::Vector2d& c, const Eigen::Vector3d& size,
              double yaw_deg, const std::string& style, double base_z = 0.0);
  void AddPanel(const std::string& name, const Eigen::Vector3d& c, const Eigen::Vector3d& normal, double w, double h,
                const std::string& style);
  bool TryPlace(const std::string& type, const std::string& name, const Eigen::Vector2d& c, const Eigen::Vector3d& size,
                double yaw_deg, const std::string& style);
  void AddWallObjects(int count);
  void PlanOrbit(PlannedOverlap* p, double theta_rad, ViewArc* arc_a, ViewArc* arc_b);
  void PlanRun(PlannedOverlap* p, double theta_rad, ViewArc* arc_a, ViewArc* arc_b);
  /// Yaw offsets of kLookAt / kLookAlong waypoints from the heading the spline really flies.
  void AimCameras(FlightPlan* f) const;
  double MaxTurnRateDegS(const FlightPlan& f) const;
  /// Slows the flight down where the camera would turn faster than ~90 deg/s.
  void LimitTurnRate(FlightPlan* f) const;
  /// Clear of walls and obstacles, turning at most ~120 deg/s, and more than one lap.
  bool FlightOk(const FlightPlan& f) const;

  SceneLayout layout_;
  int num_agents_, profile_;
  Rng* rng_;
  int cols_ = 1, rows_ = 1;
  Eigen::Vector2d cell_, origin_, space_;  // cell size, lower-left of the cell grid, space extent
  double height_ = 3.0, z_lo_ = 1.0, z_hi_ = 2.0;
  double max_orbit_m_ = 4.0;  // orbit radius limit (long arcs on a wider circle)
  double texel_m_ = 0.008, background_grey_ = 90.0, duration_s_ = 40.0;
  std::vector<AgentPlan> agents_;
  std::vector<Obstacle> obstacles_;
  std::vector<std::string> objects_;
  std::vector<Eigen::Vector3d> path_samples_;  // flight paths sampled every 0.25 m
};

}  // namespace ccm::sim
