// SceneBuilder's flights: each agent's loop through its cell with the arcs around shared
// targets spliced in, yaw offsets that keep the camera on a target along its arc, and
// speeds fitted to the flight time.
#include <algorithm>
#include <cmath>

#include "tests/sim/scene_layout.h"
#include "tests/sim/trajectory.h"

namespace ccm::sim {
namespace {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

double Wrap(double rad) { return std::atan2(std::sin(rad), std::cos(rad)); }

double ClosedLength(const std::vector<FlightWaypoint>& w) {
  double len = 0.0;
  for (size_t i = 0; i < w.size(); ++i) len += (w[(i + 1) % w.size()].p - w[i].p).norm();
  return len;
}

// A block of waypoints at an angle about the loop's centre (a cell point or a whole arc).
struct Block {
  double angle = 0.0;
  std::vector<FlightWaypoint> points;
};

double AngleAbout(const Vec2& c, const Vec3& p) { return std::atan2(p.y() - c.y(), p.x() - c.x()); }

bool Free(const FlightWaypoint& w) { return w.mode == FlightWaypoint::View::kFree; }

// A waypoint between two others: free, with the yaw of its free neighbours.
FlightWaypoint Between(const FlightWaypoint& p, const FlightWaypoint& q, const Vec3& at) {
  FlightWaypoint m;
  m.p = at;
  m.yaw_deg = Free(p) && Free(q) ? 0.5 * (p.yaw_deg + q.yaw_deg) : Free(p) ? p.yaw_deg : Free(q) ? q.yaw_deg : 0.0;
  if (!Free(p) && !Free(q) && p.mode == q.mode && (p.view - q.view).norm() < 1e-9) m.mode = p.mode, m.view = p.view;
  return m;
}

// Neighbours closer than 0.3 m make the spline kink: keep one (a shared-arc point if any).
void DropClosePoints(std::vector<FlightWaypoint>* w) {
  for (size_t i = 0; w->size() > 4 && i < w->size();) {
    const size_t j = (i + 1) % w->size();
    if (((*w)[j].p - (*w)[i].p).norm() >= 0.3) {
      ++i;
      continue;
    }
    w->erase(w->begin() + static_cast<long>(Free((*w)[j]) ? j : i));
  }
}

// Drops free points that make the path turn back on itself (the spline would loop there);
// the shared arcs stay.
void DropSharpTurns(std::vector<FlightWaypoint>* wps) {
  for (size_t i = 0; wps->size() > 4 && i < wps->size();) {
    const size_t n = wps->size();
    const Vec2 in = ((*wps)[i].p - (*wps)[(i + n - 1) % n].p).head<2>();
    const Vec2 out = ((*wps)[(i + 1) % n].p - (*wps)[i].p).head<2>();
    const bool sharp = in.norm() < 0.3 || out.norm() < 0.3 || in.normalized().dot(out.normalized()) < std::cos(110.0 * kDeg);
    // Drop the free point at the turn, else a free neighbour of it.
    const size_t victim = Free((*wps)[i]) ? i : Free((*wps)[(i + 1) % n]) ? (i + 1) % n
                                              : Free((*wps)[(i + n - 1) % n]) ? (i + n - 1) % n : n;
    if (sharp && victim < n) {
      wps->erase(wps->begin() + static_cast<long>(victim));
      i = 0;
      continue;
    }
    ++i;
  }
}

}  // namespace

std::vector<FlightWaypoint> SceneBuilder::LoopWaypoints(AgentPlan* a, double mean_speed, bool plain) {
  Rng& r = *rng_;
  std::vector<Block> blocks;
  std::vector<std::pair<double, double>> arc_spans;  // (centre angle, half span) about the centre
  for (const ViewArc& arc : a->arcs) {
    Block b;
    b.points = ArcPoints(*a, arc, mean_speed);
    Vec2 mean = Vec2::Zero();
    for (const auto& w : b.points) mean += w.p.head<2>();
    mean /= static_cast<double>(b.points.size());
    b.angle = std::atan2(mean.y() - a->center.y(), mean.x() - a->center.x());
    double half = 0.0;
    for (const auto& w : b.points) half = std::max(half, std::abs(Wrap(AngleAbout(a->center, w.p) - b.angle)));
    arc_spans.emplace_back(b.angle, half + 20.0 * kDeg);
    blocks.push_back(std::move(b));
  }
  const int n = 8;
  const double start = r.Uniform(-M_PI, M_PI);
  for (int k = 0; k < n; ++k) {
    const double ang = start + a->dir * (2.0 * M_PI * k / n + (plain ? 0.0 : r.Uniform(-0.15, 0.15)));
    bool covered = false;
    for (const auto& [c, half] : arc_spans) covered = covered || std::abs(Wrap(ang - c)) < half;
    if (covered) continue;
    const double scale = plain ? 1.0 : r.Uniform(0.85, 1.15);
    Block b;
    b.angle = Wrap(ang);
    const Vec2 p = a->center + scale * Vec2(a->rx * std::cos(ang), a->ry * std::sin(ang));
    FlightWaypoint w;
    w.p = Vec3(p.x(), p.y(), std::clamp(a->altitude + r.Uniform(-0.3, 0.3), z_lo_, z_hi_));
    w.yaw_deg = a->yaw_style == 2 && !plain ? r.Uniform(-35.0, 35.0) : a->yaw_base;
    b.points.push_back(w);
    blocks.push_back(std::move(b));
  }
  // Order by angle in the loop's sense of rotation.
  std::sort(blocks.begin(), blocks.end(), [&](const Block& x, const Block& y) {
    return Wrap(a->dir * (x.angle - start)) < Wrap(a->dir * (y.angle - start));
  });
  // Each arc is flown in the direction that joins its neighbours without turning back.
  for (size_t i = 0; i < blocks.size(); ++i) {
    Block& b = blocks[i];
    if (b.points.size() < 2) continue;
    const Vec3 prev = blocks[(i + blocks.size() - 1) % blocks.size()].points.back().p;
    const Vec3 next = blocks[(i + 1) % blocks.size()].points.front().p;
    const double keep = (b.points.front().p - prev).norm() + (b.points.back().p - next).norm();
    const double flip = (b.points.back().p - prev).norm() + (b.points.front().p - next).norm();
    if (flip < keep) std::reverse(b.points.begin(), b.points.end());
  }
  // Lead in and out of each arc along its tangent, so that the path is already turned
  // onto the arc (and the camera half way round) when the arc begins.
  for (Block& b : blocks) {
    if (b.points.size() < 2) continue;
    const auto lead = [](const FlightWaypoint& end, const FlightWaypoint& inner) {
      FlightWaypoint w;
      const Vec3 d = end.p - inner.p;
      w.p = end.p + d.normalized() * 1.2;
      w.p.z() = end.p.z();
      w.yaw_deg = 0.0;
      return w;
    };
    const FlightWaypoint in = lead(b.points[0], b.points[1]);
    const FlightWaypoint out = lead(b.points.back(), b.points[b.points.size() - 2]);
    b.points.insert(b.points.begin(), in);
    b.points.push_back(out);
  }
  std::vector<FlightWaypoint> wps;
  for (const Block& b : blocks) wps.insert(wps.end(), b.points.begin(), b.points.end());
  // Densify long legs (the spline overshoots less), keep points off walls and targets.
  for (size_t i = 0; i < wps.size(); ++i) {
    const FlightWaypoint& p = wps[i];
    const FlightWaypoint& q = wps[(i + 1) % wps.size()];
    if ((q.p - p.p).norm() > 2.5) {
      wps.insert(wps.begin() + static_cast<long>(i) + 1, Between(p, q, 0.5 * (p.p + q.p)));
      --i;
    }
  }
  KeepClear(&wps);
  return wps;
}

void SceneBuilder::KeepClear(std::vector<FlightWaypoint>* wps) const {
  for (int pass = 0; pass < 6; ++pass) {
    bool moved = false;
    for (FlightWaypoint& w : *wps) {
      Vec2 p = w.p.head<2>();
      p.x() = std::clamp(p.x(), 0.8, space_.x() - 0.8);
      p.y() = std::clamp(p.y(), std::min(0.8, 0.5 * space_.y()), std::max(space_.y() - 0.8, 0.5 * space_.y()));
      for (const Obstacle& o : obstacles_) {
        if (o.top < w.p.z() - 0.5 || !o.Contains(p, 0.9)) continue;
        const Vec2 away = (p - o.center).norm() > 1e-6 ? Vec2((p - o.center).normalized()) : Vec2::UnitX();
        p += away * 0.5;
        moved = true;
      }
      w.p.head<2>() = p;
    }
    if (!moved) break;
  }
  DropSharpTurns(wps);
}

void SceneBuilder::AimCameras(FlightPlan* f) const {
  FlightPlan zero = *f;  // positions do not depend on the yaw offsets
  std::string error;
  const auto traj = Trajectory::Create(Spec(zero), &error);
  if (!traj) return;
  for (FlightWaypoint& w : f->waypoints) {
    if (Free(w)) continue;
    double best_t = 0.0, best_d = 1e300;
    for (double t = 0.0; t <= traj->duration_s(); t += 0.05) {
      const double d = (traj->Position(t) - w.p).squaredNorm();
      if (d < best_d) best_d = d, best_t = t;
    }
    // The simulator's heading: the chord +-1 m of arc length around the position.
    const double speed = std::max(0.05, traj->Velocity(best_t).norm());
    const Vec3 chord = traj->Position(best_t + 1.0 / speed) - traj->Position(std::max(0.0, best_t - 1.0 / speed));
    const double heading = std::atan2(chord.y(), chord.x());
    const Vec2 to = w.mode == FlightWaypoint::View::kLookAt ? Vec2(w.view - w.p.head<2>()) : w.view;
    // Within +-120 deg of the direction of travel: offsets interpolate without wrapping, so
    // two neighbours never swing the camera the long way round.
    w.yaw_deg = std::clamp(Wrap(std::atan2(to.y(), to.x()) - heading) / kDeg, -120.0, 120.0);
  }
  // Free points next to an arc turn halfway towards it: the camera swings round over two
  // legs instead of one (fast turns stay, whip pans go).
  auto& w = f->waypoints;
  std::vector<double> yaw(w.size());
  for (size_t i = 0; i < w.size(); ++i) yaw[i] = w[i].yaw_deg;
  for (size_t i = 0; i < w.size(); ++i) {
    if (!Free(w[i])) continue;
    const FlightWaypoint& prev = w[(i + w.size() - 1) % w.size()];
    const FlightWaypoint& next = w[(i + 1) % w.size()];
    if (!Free(prev)) yaw[i] = 0.5 * (yaw[i] + prev.yaw_deg);
    else if (!Free(next)) yaw[i] = 0.5 * (yaw[i] + next.yaw_deg);
  }
  for (size_t i = 0; i < w.size(); ++i) w[i].yaw_deg = yaw[i];
}

void SceneBuilder::FitSpeeds(AgentPlan* a, double duration_s) {
  FlightPlan& f = a->flight;
  const double cap = layout_ == SceneLayout::kYard ? 2.8 : 2.0;
  const double loop = ClosedLength(f.waypoints);
  const double mean = 0.5 * (f.min_speed + f.max_speed);
  // 1.3-2.5 laps (counted on the waypoint polygon; the spline is a little longer): every
  // agent revisits its own path (loops to close).
  double factor = 1.0;
  if (mean * duration_s < 1.3 * loop) factor = 1.3 * loop / (mean * duration_s);
  if (mean * duration_s > 2.5 * loop) factor = 2.5 * loop / (mean * duration_s);
  factor = std::min(factor, cap / f.max_speed);
  factor = std::max(factor, 0.3 / f.min_speed);
  f.min_speed *= factor;
  f.max_speed *= factor;
  f.duration_s = duration_s;
  // Still under 1.2 laps at the fastest allowed speeds: fly longer instead.
  const double laps = 0.5 * (f.min_speed + f.max_speed) * duration_s / loop;
  if (laps < 1.35) f.duration_s = std::min(duration_s * 2.0, duration_s * 1.35 / laps);
}

TrajectorySpec SceneBuilder::Spec(const FlightPlan& f) const {
  TrajectorySpec t;
  for (const FlightWaypoint& w : f.waypoints) t.waypoints.push_back({w.p, w.yaw_deg});
  t.loop = true;
  t.duration_s = f.duration_s;
  t.min_speed_mps = f.min_speed;
  t.max_speed_mps = f.max_speed;
  t.speed_period_s = f.speed_period;
  t.pitch_deg = f.pitch_deg;
  t.wobble_deg = f.wobble_deg;
  t.look_ahead_m = f.look_ahead_m;
  return t;
}

bool SceneBuilder::DetourOnce(FlightPlan* f, bool climb) const {
  std::string error;
  const auto traj = Trajectory::Create(Spec(*f), &error);
  if (!traj) return false;
  for (double t = 0.0; t <= traj->duration_s(); t += 0.05) {
    const Vec3 p = traj->Position(t);
    Vec2 q = p.head<2>();
    bool hit = !InSpace(q, 0.5);
    double z = p.z();
    if (hit) {
      q = q.cwiseMax(Vec2(1.0, 1.0)).cwiseMin(space_ - Vec2(1.0, 1.0));
    } else {
      for (const Obstacle& o : obstacles_) {
        if (o.top < p.z() - 0.4 || !o.Contains(q, 0.4)) continue;
        hit = true;
        // Round it; where rounding keeps failing, over it (as a pilot would), if the
        // ceiling leaves room.
        if (climb && (layout_ == SceneLayout::kYard || o.top + 1.3 < height_)) {
          z = o.top + 0.9;
          break;
        }
        const Vec2 away = (q - o.center).norm() > 1e-6 ? Vec2((q - o.center).normalized()) : Vec2::UnitY();
        q = o.center + away * (o.half.norm() + 0.9);
        break;
      }
    }
    if (!hit) continue;
    // Insert the detour into the leg of the loop the spline was on.
    auto& w = f->waypoints;
    size_t best = 0;
    double best_d = 1e300;
    for (size_t i = 0; i < w.size(); ++i) {
      const Vec2 a = w[i].p.head<2>(), b = w[(i + 1) % w.size()].p.head<2>();
      const double l = std::clamp((p.head<2>() - a).dot(b - a) / std::max(1e-9, (b - a).squaredNorm()), 0.0, 1.0);
      const double d = (a + l * (b - a) - p.head<2>()).norm();
      if (d < best_d) best_d = d, best = i;
    }
    if (z != p.z()) {
      w[best].p.z() = std::max(w[best].p.z(), z);
      w[(best + 1) % w.size()].p.z() = std::max(w[(best + 1) % w.size()].p.z(), z);
      return true;
    }
    const FlightWaypoint& a = w[best];
    const FlightWaypoint& b = w[(best + 1) % w.size()];
    w.insert(w.begin() + static_cast<long>(best) + 1, Between(a, b, Vec3(q.x(), q.y(), p.z())));
    return true;
  }
  return false;
}

double SceneBuilder::MaxTurnRateDegS(const FlightPlan& f) const {
  std::string error;
  const auto traj = Trajectory::Create(Spec(f), &error);
  if (!traj) return 0.0;
  double worst = 0.0;
  constexpr double kStep = 0.05;
  SE3 prev = traj->WorldFromCam(0.0);
  for (double t = kStep; t <= traj->duration_s(); t += kStep) {
    const SE3 now = traj->WorldFromCam(t);
    const double rate = Eigen::AngleAxisd(prev.rotation().conjugate() * now.rotation()).angle() / kDeg / kStep;
    worst = std::max(worst, rate);
    prev = now;
  }
  return worst;
}

void SceneBuilder::LimitTurnRate(FlightPlan* f) const {
  // A pilot slows down for sharp turns: keep the camera under ~90 deg/s (EuRoC's flights
  // peak there), flying longer so that the loop is still flown more than once.
  constexpr double kMaxRate = 90.0;
  for (int i = 0; i < 3; ++i) {
    const double rate = MaxTurnRateDegS(*f);
    if (rate <= kMaxRate) return;
    const double factor = std::max(0.25 / f->min_speed, 0.95 * kMaxRate / rate);
    if (factor >= 1.0) return;
    f->min_speed *= factor;
    f->max_speed *= factor;
    f->duration_s = std::min(f->duration_s / factor, 2.0 * f->duration_s);
  }
}

bool SceneBuilder::FlightOk(const FlightPlan& f) const {
  FlightPlan probe = f;
  const bool blocked = DetourOnce(&probe, false);  // still meets a wall or an obstacle
  std::string error;
  const auto traj = Trajectory::Create(Spec(f), &error);
  const double rate = MaxTurnRateDegS(f);
  const double laps = traj ? traj->ArcLength(f.duration_s) / ClosedLength(f.waypoints) : 0;
  return !blocked && traj && rate <= 125.0 && laps >= 1.1;
}

void SceneBuilder::BuildFlights(double duration_s) {
  duration_s_ = duration_s;
  for (AgentPlan& a : agents_) {
    const FlightPlan base = a.flight;
    // A few layouts of the loop (new random bends each time); the last ones without the
    // shared arcs, which a loop cannot always join smoothly, the very last a plain ellipse.
    // The plan stays what it was:
    // the ground truth tells what the agents really saw.
    for (int attempt = 0; attempt < 8; ++attempt) {
      if (attempt == 6 && !a.arcs.empty()) a.arcs.clear(), a.arcs_dropped = true;
      a.flight = base;
      const double mean = 0.5 * (a.flight.min_speed + a.flight.max_speed);
      a.flight.waypoints = LoopWaypoints(&a, mean, /*plain=*/attempt == 7);
      FitSpeeds(&a, duration_s);
      // The spline swings wider than the waypoints: detour where it meets a wall or a target.
      for (int i = 0; i < 16 && DetourOnce(&a.flight, i >= 8); ++i) {
      }
      DropSharpTurns(&a.flight.waypoints);
      DropClosePoints(&a.flight.waypoints);
      AimCameras(&a.flight);
      LimitTurnRate(&a.flight);
      if (FlightOk(a.flight)) break;
    }
    duration_s_ = std::max(duration_s_, a.flight.duration_s);
  }
  // One flight time for the scene: agents that needed longer set it.
  for (AgentPlan& a : agents_) {
    a.flight.duration_s = duration_s_;
    std::string error;
    const auto traj = Trajectory::Create(Spec(a.flight), &error);
    if (!traj) continue;
    for (double t = 0.0; t <= traj->duration_s(); t += 0.1) path_samples_.push_back(traj->Position(t));
  }
}

}  // namespace ccm::sim
