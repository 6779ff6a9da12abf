#include "tests/sim/scene_layout.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>

namespace ccm::sim {
namespace {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

double Cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }
Vec2 Rotate(const Vec2& v, double rad) {
  return {std::cos(rad) * v.x() - std::sin(rad) * v.y(), std::sin(rad) * v.x() + std::cos(rad) * v.y()};
}

const char* WallStyle(Rng* rng, int profile) {
  if (profile == 0) return "rich";
  if (profile == 1) return rng->Uniform() < 0.8 ? "mixed" : "rich";
  return rng->Uniform() < 0.6 ? "weak" : "mixed";
}

// Halls and yards: one row up to 3 agents, two up to 8, then 3-4 rows (a team-scale scene:
// 9-16 agents, each overlapping up to four neighbours).
int RowsOfCells(int agents) { return agents > 12 ? 4 : agents > 8 ? 3 : agents >= 4 ? 2 : 1; }

}  // namespace

bool SceneBuilder::Obstacle::Contains(const Vec2& p, double margin) const {
  const Vec2 local = Rotate(p - center, -yaw_rad);
  return std::abs(local.x()) <= half.x() + margin && std::abs(local.y()) <= half.y() + margin;
}

SceneBuilder::SceneBuilder(SceneLayout layout, int agents, int profile, Rng* rng)
    : layout_(layout), num_agents_(agents), profile_(profile), rng_(rng) {
  MakeSpace();
  MakeAgents();
}

void SceneBuilder::MakeSpace() {
  Rng& r = *rng_;
  Vec2 margin = Vec2::Zero();
  switch (layout_) {
    case SceneLayout::kRoom:
      cols_ = num_agents_;
      cell_ = {r.Uniform(4.5, 6.5), r.Uniform(4.5, 7.0)};
      margin = {r.Uniform(0.8, 1.5), r.Uniform(0.8, 1.5)};
      height_ = r.Uniform(2.8, 3.6);
      z_lo_ = 0.9, z_hi_ = std::min(2.0, height_ - 0.7);
      break;
    case SceneLayout::kHall:
      rows_ = RowsOfCells(num_agents_);
      cols_ = (num_agents_ + rows_ - 1) / rows_;
      cell_ = {r.Uniform(7.0, 10.0), r.Uniform(7.0, 10.0)};
      margin = {r.Uniform(1.0, 3.0), r.Uniform(1.0, 3.0)};
      height_ = r.Uniform(5.0, 8.0);
      z_lo_ = 1.2, z_hi_ = 3.2;
      texel_m_ = cell_.x() * cols_ > 30.0 ? 0.01 : 0.008;
      break;
    case SceneLayout::kYard:
      rows_ = RowsOfCells(num_agents_);
      cols_ = (num_agents_ + rows_ - 1) / rows_;
      cell_ = {r.Uniform(10.0, 14.0), r.Uniform(10.0, 14.0)};
      margin = {r.Uniform(3.0, 6.0), r.Uniform(3.0, 6.0)};
      height_ = r.Uniform(5.0, 12.0);
      z_lo_ = 1.8, z_hi_ = 5.0;
      max_orbit_m_ = 7.0;
      texel_m_ = 0.014;
      background_grey_ = r.Uniform(150.0, 210.0);
      break;
    case SceneLayout::kCorridor:
      cols_ = num_agents_;
      cell_ = {r.Uniform(8.0, 12.0), r.Uniform(3.0, 5.0)};
      margin = {r.Uniform(2.0, 4.0), 0.0};
      height_ = r.Uniform(2.6, 3.4);
      z_lo_ = 0.9, z_hi_ = std::min(1.9, height_ - 0.7);
      break;
  }
  origin_ = margin;
  space_ = {cols_ * cell_.x() + 2.0 * margin.x(), rows_ * cell_.y() + 2.0 * margin.y()};
  char buf[256];
  if (layout_ != SceneLayout::kYard) {
    std::snprintf(buf, sizeof(buf),
                  "{type: room, name: space, min: [0, 0, 0], max: [%.2f, %.2f, %.2f], floor: %s, ceiling: weak, "
                  "walls: %s, grey: %.0f}",
                  space_.x(), space_.y(), height_, profile_ == 2 ? "weak" : "mixed", WallStyle(rng_, profile_),
                  r.Uniform(95.0, 165.0));
    objects_.push_back(buf);
    return;
  }
  // A yard: ground tiles and building facades of varied height around it, sky above.
  const int nx = static_cast<int>(std::ceil(space_.x() / 12.0)), ny = static_cast<int>(std::ceil(space_.y() / 12.0));
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      AddPanel("ground_" + std::to_string(i) + "_" + std::to_string(j),
               {(i + 0.5) * space_.x() / nx, (j + 0.5) * space_.y() / ny, 0.0}, Vec3::UnitZ(), space_.x() / nx + 0.01,
               space_.y() / ny + 0.01, profile_ == 2 || r.Uniform() < 0.3 ? "weak" : "mixed");
    }
  }
  const Vec2 corners[4] = {{0, 0}, {space_.x(), 0}, {space_.x(), space_.y()}, {0, space_.y()}};
  for (int side = 0; side < 4; ++side) {
    const Vec2 a = corners[side], b = corners[(side + 1) % 4];
    const double len = (b - a).norm();
    const Vec2 along = (b - a) / len, inward = Rotate(along, M_PI / 2);
    double s = 0.0;
    int k = 0;
    while (s < len - 1e-6) {
      const double w = std::min(len - s, r.Uniform(5.0, 12.0));
      const double h = std::clamp(height_ * r.Uniform(0.6, 1.4), z_hi_ + 1.5, 16.0);
      const Vec2 c = a + along * (s + 0.5 * w);
      AddPanel("facade_" + std::to_string(side) + "_" + std::to_string(k++), {c.x(), c.y(), 0.5 * h},
               {inward.x(), inward.y(), 0.0}, w + 0.01, h, WallStyle(rng_, profile_));
      s += w;
    }
  }
}

void SceneBuilder::MakeAgents() {
  Rng& r = *rng_;
  for (int i = 0; i < num_agents_; ++i) {
    AgentPlan a;
    const int col = i % cols_, row = i / cols_;
    a.cell_center = origin_ + Vec2((col + 0.5) * cell_.x(), (row + 0.5) * cell_.y());
    a.center = a.cell_center + Vec2(r.Uniform(-0.08, 0.08) * cell_.x(), r.Uniform(-0.08, 0.08) * cell_.y());
    if (layout_ == SceneLayout::kCorridor) {
      a.center.y() = a.cell_center.y();
      a.rx = r.Uniform(0.3, 0.4) * cell_.x();
      a.ry = std::max(0.35, 0.5 * cell_.y() - r.Uniform(0.8, 1.1));
    } else {
      a.rx = r.Uniform(0.22, 0.32) * cell_.x();
      a.ry = r.Uniform(0.22, 0.32) * cell_.y();
    }
    a.dir = r.Uniform() < 0.5 ? 1 : -1;
    a.altitude = r.Uniform(z_lo_, z_hi_);
    a.yaw_style = r.Pick({0.5, 0.25, 0.25});
    a.yaw_base = a.yaw_style == 1 ? (r.Uniform() < 0.5 ? -1 : 1) * r.Uniform(25.0, 50.0) : r.Uniform(-10.0, 10.0);
    FlightPlan& f = a.flight;
    const bool yard = layout_ == SceneLayout::kYard;
    f.min_speed = yard ? r.Uniform(0.6, 1.5) : r.Uniform(0.3, 0.8);
    f.max_speed = f.min_speed + (yard ? r.Uniform(0.5, 1.5) : r.Uniform(0.3, 1.0));
    f.speed_period = r.Uniform(8.0, 25.0);
    f.pitch_deg = yard ? -r.Uniform(15.0, 35.0) : -r.Uniform(5.0, 22.0);
    f.wobble_deg = r.Uniform(0.5, 3.0);
    agents_.push_back(a);
  }
}

std::vector<std::pair<int, int>> SceneBuilder::NeighbourPairs() const {
  std::vector<std::pair<int, int>> out;
  for (int i = 0; i < num_agents_; ++i) {
    for (int j = i + 1; j < num_agents_; ++j) {
      const int dc = std::abs(i % cols_ - j % cols_), dr = std::abs(i / cols_ - j / cols_);
      if (dc + dr == 1) out.emplace_back(i, j);
    }
  }
  return out;
}

void SceneBuilder::PlanSharedTarget(PlannedOverlap* p) {
  Rng& r = *rng_;
  double theta_deg = 0.0;
  switch (p->kind) {
    case PlannedOverlapKind::kSame: theta_deg = r.Uniform(0.0, 10.0), p->seconds = r.Uniform(4.0, 7.0); break;
    case PlannedOverlapKind::kOblique: theta_deg = r.Uniform(30.0, 60.0), p->seconds = r.Uniform(4.0, 7.0); break;
    case PlannedOverlapKind::kBrief: theta_deg = r.Uniform(0.0, 15.0), p->seconds = r.Uniform(2.0, 3.0); break;
    case PlannedOverlapKind::kLong: theta_deg = r.Uniform(0.0, 12.0), p->seconds = r.Uniform(8.0, 13.0); break;
    case PlannedOverlapKind::kNone: return;
  }
  p->view_angle_deg = theta_deg;
  ViewArc arc_a, arc_b;
  arc_a.seconds = arc_b.seconds = p->seconds;
  // Long overlaps and corridors: a straight run beside a partition or the wall; otherwise an
  // orbit round a target object.
  if (layout_ == SceneLayout::kCorridor || p->kind == PlannedOverlapKind::kLong) {
    PlanRun(p, theta_deg * kDeg, &arc_a, &arc_b);
  } else {
    PlanOrbit(p, theta_deg * kDeg, &arc_a, &arc_b);
  }
  agents_[p->agent_a].arcs.push_back(arc_a);
  agents_[p->agent_b].arcs.push_back(arc_b);
}

void SceneBuilder::PlanOrbit(PlannedOverlap* p, double theta, ViewArc* arc_a, ViewArc* arc_b) {
  Rng& r = *rng_;
  const AgentPlan& a = agents_[p->agent_a];
  const AgentPlan& b = agents_[p->agent_b];
  const Vec2 n = (b.cell_center - a.cell_center).normalized();  // a's cell -> b's cell
  const Vec2 u(-n.y(), n.x());
  const Vec2 mid = 0.5 * (a.cell_center + b.cell_center);
  const bool yard = layout_ == SceneLayout::kYard;
  const double along = std::abs(u.x()) > 0.5 ? cell_.x() : cell_.y();
  const Vec2 target = mid + u * r.Uniform(-0.25, 0.25) * along;
  const Vec3 size = yard ? Vec3(r.Uniform(1.2, 2.5), r.Uniform(1.2, 2.5), r.Uniform(1.5, 3.5))
                         : Vec3(r.Uniform(0.6, 1.4), r.Uniform(0.6, 1.4), r.Uniform(0.8, std::min(2.2, height_ - 0.5)));
  AddBox("box", "target_" + std::to_string(p->agent_a) + "_" + std::to_string(p->agent_b), target, size,
         r.Uniform(-45.0, 45.0), r.Uniform() < 0.7 ? "rich" : ObjectStyleForProfile(rng_, profile_));
  const double clear = 0.5 * size.head<2>().norm() + (yard ? 2.0 : 1.3);
  // a views from along the boundary, leaning into its own cell; b from theta further round
  // towards its cell.
  const double s = r.Uniform() < 0.5 ? -1.0 : 1.0;
  const double lean = r.Uniform(0.0, 20.0) * kDeg;
  const Vec2 da = (s * u * std::cos(lean) - n * std::sin(lean)).normalized();
  const double towards_b = Cross2(da, n) > 0 ? 1.0 : -1.0;
  const double radius = std::max(clear, yard ? r.Uniform(3.0, 5.0) : r.Uniform(2.0, 3.2));
  arc_a->target = arc_b->target = target;
  arc_a->direction = da;
  arc_b->direction = Rotate(da, towards_b * theta);
  arc_a->radius = radius + r.Uniform(-0.2, 0.3);
  arc_b->radius = radius + r.Uniform(-0.2, 0.3);
}

void SceneBuilder::PlanRun(PlannedOverlap* p, double theta, ViewArc* arc_a, ViewArc* arc_b) {
  Rng& r = *rng_;
  const AgentPlan& a = agents_[p->agent_a];
  const AgentPlan& b = agents_[p->agent_b];
  const std::string name = "target_" + std::to_string(p->agent_a) + "_" + std::to_string(p->agent_b);
  const double speed = 0.25 * (a.flight.min_speed + a.flight.max_speed + b.flight.min_speed + b.flight.max_speed);
  double length = std::max(1.5, p->seconds * speed);
  Vec2 middle, along, facing;  // run line, its direction, and the camera's base direction
  if (layout_ == SceneLayout::kCorridor) {
    // A cabinet and a poster on one side wall at the cells' boundary.
    const bool low_wall = r.Uniform() < 0.5;
    const double wall_y = low_wall ? 0.0 : space_.y(), inward = low_wall ? 1.0 : -1.0;
    const double x = 0.5 * (a.cell_center.x() + b.cell_center.x());
    const Vec2 cab_size(r.Uniform(0.8, 1.6), r.Uniform(0.4, 0.6));
    const Vec2 cab(x + r.Uniform(-1.0, 1.0), wall_y + inward * (0.5 * cab_size.y() + 0.02));
    AddBox("box", name, cab, {cab_size.x(), cab_size.y(), r.Uniform(0.9, 1.8)}, 0.0,
           ObjectStyleForProfile(rng_, profile_));
    AddPanel(name + "_poster", {x + r.Uniform(-1.5, 1.5), wall_y + inward * 0.005, r.Uniform(1.4, 2.0)},
             {0.0, inward, 0.0}, r.Uniform(0.6, 1.4), r.Uniform(0.4, 0.8), "rich");
    const double dist = r.Uniform(1.1, std::max(1.15, std::min(2.0, cell_.y() - 0.9)));
    middle = {x, wall_y + inward * dist};
    along = Vec2::UnitX();
    facing = {0.0, -inward};
  } else {
    // A partition (shelf row; in a yard a container row) on the cells' boundary; both
    // agents fly along one of its faces.
    const Vec2 n = (b.cell_center - a.cell_center).normalized();
    const Vec2 u(-n.y(), n.x());
    const bool yard = layout_ == SceneLayout::kYard;
    const double span = std::abs(u.x()) > 0.5 ? cell_.x() : cell_.y();
    const double plen = std::min(0.6 * span, std::max(yard ? 6.0 : 4.0, length));
    const double depth = yard ? 2.4 : r.Uniform(0.4, 0.7);
    const double h = yard ? 2.6 : r.Uniform(1.4, std::max(1.5, std::min(2.5, height_ - 0.5)));
    const Vec2 c = 0.5 * (a.cell_center + b.cell_center) + u * r.Uniform(-0.1, 0.1) * span;
    const double yaw = std::atan2(u.y(), u.x()) / kDeg;
    AddBox("box", name, c, {plen, depth, h}, yaw, r.Uniform() < 0.6 ? "rich" : ObjectStyleForProfile(rng_, profile_));
    const double side = r.Uniform() < 0.5 ? -1.0 : 1.0;
    const double dist = 0.5 * depth + (yard ? r.Uniform(2.5, 4.0) : r.Uniform(1.4, 2.4));
    middle = c + side * n * dist;
    along = u;
    facing = -side * n;
    length = std::min(length, plen + 1.0);
  }
  const double base = r.Uniform(-10.0, 10.0) * kDeg, sign = r.Uniform() < 0.5 ? -1.0 : 1.0;
  for (ViewArc* arc : {arc_a, arc_b}) {
    arc->run = true;
    arc->run_middle = middle + facing * r.Uniform(-0.2, 0.2);
    arc->run_dir = along;
    arc->view_dir = Rotate(facing, arc == arc_a ? base : base + sign * theta);
  }
}

std::vector<FlightWaypoint> SceneBuilder::ArcPoints(const AgentPlan& a, const ViewArc& arc, double mean_speed) const {
  double length = arc.seconds * mean_speed;
  double radius = arc.radius;
  constexpr double kMaxHalf = 40.0 * kDeg;  // wider arcs turn back on the loop's legs
  if (!arc.run && 0.5 * length / radius > kMaxHalf) radius = std::max(radius, std::min(max_orbit_m_, 0.5 * length / kMaxHalf));
  const double half = std::min(kMaxHalf, 0.5 * length / radius);
  if (!arc.run) length = 2.0 * half * radius;
  std::vector<FlightWaypoint> out;
  const int m = std::max(3, static_cast<int>(std::ceil(length / 0.9)) + 1);
  for (int k = 0; k < m; ++k) {
    const double f = static_cast<double>(k) / (m - 1) - 0.5;
    FlightWaypoint w;
    Vec2 p;
    if (arc.run) {
      p = arc.run_middle + arc.run_dir * (f * length);
      w.mode = FlightWaypoint::View::kLookAlong;
      w.view = arc.view_dir;
    } else {
      p = arc.target + radius * Rotate(arc.direction, 2.0 * f * half);
      w.mode = FlightWaypoint::View::kLookAt;
      w.view = arc.target;
    }
    w.p = Vec3(p.x(), p.y(), a.altitude + rng_->Uniform(-0.1, 0.1));
    out.push_back(w);
  }
  // Fly the arc in the loop's sense of rotation about the agent's centre.
  const Vec2 s = out.front().p.head<2>() - a.center, e = out.back().p.head<2>() - a.center;
  if (Cross2(s, e) * a.dir < 0) std::reverse(out.begin(), out.end());
  return out;
}

}  // namespace ccm::sim
