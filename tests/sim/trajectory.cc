#include "tests/sim/trajectory.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace ccm::sim {

namespace {
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kArcStep = 0.01;  // arc-length table resolution in the spline parameter [m]
}  // namespace

std::string TrajectorySpec::Validate() const {
  if (waypoints.size() < 2) return "needs at least 2 waypoints";
  for (size_t i = 1; i < waypoints.size(); ++i)
    if ((waypoints[i].position_m - waypoints[i - 1].position_m).norm() < 0.05)
      return "waypoints " + std::to_string(i - 1) + " and " + std::to_string(i) + " are closer than 5 cm";
  if (loop && waypoints.size() < 3) return "a loop needs at least 3 waypoints";
  if (!(duration_s > 0.0)) return "duration_s must be > 0";
  if (!(min_speed_mps > 0.0 && max_speed_mps >= min_speed_mps && max_speed_mps < 20.0))
    return "speeds must satisfy 0 < min_speed_mps <= max_speed_mps < 20";
  if (!(speed_period_s > 0.1)) return "speed_period_s must be > 0.1";
  if (!(std::abs(pitch_deg) < 89.0)) return "pitch_deg must be in (-89, 89)";
  if (!(wobble_deg >= 0.0 && wobble_deg < 20.0)) return "wobble_deg must be in [0, 20)";
  if (!(look_ahead_m > 0.0)) return "look_ahead_m must be > 0";
  return {};
}

std::unique_ptr<Trajectory> Trajectory::Create(const TrajectorySpec& spec, std::string* error) {
  std::string e = spec.Validate();
  std::unique_ptr<Trajectory> traj;
  if (e.empty()) {
    traj.reset(new Trajectory(spec));
    std::vector<Waypoint> points = spec.waypoints;
    if (spec.loop) {
      double loop_len = 0.0;
      for (size_t i = 0; i < points.size(); ++i)
        loop_len += (points[(i + 1) % points.size()].position_m - points[i].position_m).norm();
      const double needed = spec.duration_s * spec.max_speed_mps + 2.0 * spec.look_ahead_m + 1.0;
      const int repeats = static_cast<int>(std::ceil(needed / loop_len)) + 1;
      points.clear();
      for (int r = 0; r < repeats; ++r) points.insert(points.end(), spec.waypoints.begin(), spec.waypoints.end());
      points.push_back(spec.waypoints.front());
    }
    traj->Build(points);
    const double flown = traj->ArcLength(spec.duration_s);
    if (flown > traj->path_length_m())
      e = "path of " + std::to_string(traj->path_length_m()) + " m is too short for " +
          std::to_string(spec.duration_s) + " s of flight (needs " + std::to_string(flown) +
          " m); add waypoints, set loop: true or shorten the duration";
  }
  if (!e.empty()) {
    if (error) *error = e;
    return nullptr;
  }
  return traj;
}

void Trajectory::Build(const std::vector<Waypoint>& points) {
  const size_t n = points.size();
  knots_.assign(n, 0.0);
  values_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    values_[i] << points[i].position_m, points[i].yaw_offset_deg * kDegToRad;
    if (i > 0) knots_[i] = knots_[i - 1] + (points[i].position_m - points[i - 1].position_m).norm();
  }
  // Natural cubic spline: tridiagonal system for the second derivatives (Thomas algorithm).
  second_.assign(n, Eigen::Vector4d::Zero());
  std::vector<double> c(n, 0.0);
  std::vector<Eigen::Vector4d> d(n, Eigen::Vector4d::Zero());
  for (size_t i = 1; i + 1 < n; ++i) {
    const double h0 = knots_[i] - knots_[i - 1], h1 = knots_[i + 1] - knots_[i];
    const Eigen::Vector4d rhs = 6.0 * ((values_[i + 1] - values_[i]) / h1 - (values_[i] - values_[i - 1]) / h0);
    const double diag = 2.0 * (h0 + h1) - h0 * c[i - 1];
    c[i] = h1 / diag;
    d[i] = (rhs - h0 * d[i - 1]) / diag;
  }
  for (size_t i = n - 1; i-- > 1;) second_[i] = d[i] - c[i] * second_[i + 1];
  // Arc-length table.
  arc_tau_.clear();
  arc_.clear();
  Eigen::Vector3d prev = AtKnotParam(0.0).head<3>();
  double s = 0.0;
  for (double tau = 0.0;; tau += kArcStep) {
    tau = std::min(tau, knots_.back());
    const Eigen::Vector3d p = AtKnotParam(tau).head<3>();
    s += (p - prev).norm();
    prev = p;
    arc_tau_.push_back(tau);
    arc_.push_back(s);
    if (tau >= knots_.back()) break;
  }
}

Eigen::Vector4d Trajectory::AtKnotParam(double tau) const {
  tau = std::clamp(tau, knots_.front(), knots_.back());
  const size_t i = std::min<size_t>(std::upper_bound(knots_.begin(), knots_.end(), tau) - knots_.begin(),
                                    knots_.size() - 1);
  const size_t i0 = i - 1;
  const double h = knots_[i] - knots_[i0];
  const double a = (knots_[i] - tau) / h, b = (tau - knots_[i0]) / h;
  return a * values_[i0] + b * values_[i] +
         ((a * a * a - a) * second_[i0] + (b * b * b - b) * second_[i]) * (h * h / 6.0);
}

Eigen::Vector4d Trajectory::AtArc(double s) const {
  s = std::clamp(s, 0.0, arc_.back());
  const size_t i = std::min<size_t>(std::upper_bound(arc_.begin(), arc_.end(), s) - arc_.begin(), arc_.size() - 1);
  if (i == 0) return AtKnotParam(arc_tau_.front());
  const double span = arc_[i] - arc_[i - 1];
  const double w = span > 0.0 ? (s - arc_[i - 1]) / span : 0.0;
  return AtKnotParam(arc_tau_[i - 1] + w * (arc_tau_[i] - arc_tau_[i - 1]));
}

double Trajectory::ArcLength(double t) const {
  // v(t) = mid + amp * sin(w t): integrates in closed form, stays within [min, max].
  const double mid = 0.5 * (spec_.min_speed_mps + spec_.max_speed_mps);
  const double amp = 0.5 * (spec_.max_speed_mps - spec_.min_speed_mps);
  const double w = 2.0 * M_PI / spec_.speed_period_s;
  return mid * t + amp / w * (1.0 - std::cos(w * t));
}

Eigen::Vector3d Trajectory::Position(double t) const { return AtArc(ArcLength(t)).head<3>(); }

Eigen::Vector3d Trajectory::Velocity(double t) const {
  const double h = 1e-3;
  const double t0 = std::max(t - h, 0.0);  // the path starts at t = 0: one-sided there
  return (Position(t + h) - Position(t0)) / (t + h - t0);
}

SE3 Trajectory::WorldFromCam(double t) const {
  const double s = ArcLength(t);
  const Eigen::Vector4d here = AtArc(s);
  const Eigen::Vector3d dir = AtArc(s + spec_.look_ahead_m).head<3>() - AtArc(s - spec_.look_ahead_m).head<3>();
  const double heading = std::atan2(dir.y(), dir.x());
  const double yaw = heading + here[3];
  const double pitch = spec_.pitch_deg * kDegToRad + spec_.wobble_deg * kDegToRad * std::sin(2 * M_PI * t / 6.1);
  const double roll = spec_.wobble_deg * kDegToRad * std::sin(2 * M_PI * t / 4.3 + 1.0);
  const Eigen::Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d R;
  R << right, down, forward;  // columns: camera x (right), y (down), z (forward) in the world
  R = R * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return SE3(R, here.head<3>());
}

}  // namespace ccm::sim
