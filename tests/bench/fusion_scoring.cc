#include "tests/bench/fusion_scoring.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <numeric>
#include <optional>

#include <Eigen/Geometry>

#include "slam_core/eval/evaluator.h"
#include "slam_core/eval/metrics.h"

namespace ccm::bench {
namespace {

// Keyframes whose ground-truth views share less than this (of the smaller one) saw nothing
// in common.
constexpr double kMinViewShare = 0.05;

double Seconds(const sim::Simulation& sim, int64_t stamp_ns) {
  return static_cast<double>(stamp_ns - sim.scenario().start_stamp_ns) * 1e-9;
}

int AgentIndex(const report::RunResult& r, AgentId id) {
  for (size_t i = 0; i < r.agents.size(); ++i) {
    if (r.agents[i].id == id) return static_cast<int>(i);
  }
  return -1;
}

std::optional<int64_t> KeyframeStamp(const report::RunResult& r, KeyframeId kf) {
  const int a = AgentIndex(r, kf.agent());
  if (a < 0) return std::nullopt;
  for (const ServerKeyframePose& p : r.agents[a].server_keyframes) {
    if (p.id == kf) return p.stamp_ns;
  }
  return std::nullopt;
}

// Metres per VO unit around a stamp: the agent's VO keyframes within 3 s of it, aligned on
// their own (the local scale a server map has before anything rescales it).
std::optional<double> LocalVoScale(const report::AgentRunResult& a, int64_t stamp_ns) {
  constexpr int64_t kWindowNs = 3'000'000'000;
  for (const auto& [segment, t] : a.vo_segments) {
    if (t.empty() || stamp_ns < t.front().stamp_ns || stamp_ns > t.back().stamp_ns) continue;
    Trajectory near;
    for (const StampedPose& p : t) {
      if (std::llabs(p.stamp_ns - stamp_ns) <= kWindowNs) near.push_back(p);
    }
    EvalReport rep;
    std::string error;
    if (near.size() < 5 || !Evaluate({{a.name, a.ground_truth, near}}, EvalOptions{}, &rep, &error)) return std::nullopt;
    return rep.agents[0].gt_from_est.scale();
  }
  return std::nullopt;
}

DetectionCheck Check(const sim::Simulation& sim, const sim::OverlapTruth& truth, const report::RunResult& r,
                     const ServerEvent& e) {
  DetectionCheck c;
  c.event = e;
  const int qa = AgentIndex(r, e.query.agent()), ca = AgentIndex(r, e.candidate.agent());
  const auto qs = KeyframeStamp(r, e.query), cs = KeyframeStamp(r, e.candidate);
  if (qa < 0 || ca < 0 || !qs || !cs) {
    c.wrong = true;  // cannot be placed: counted, so that it is looked at
    return c;
  }
  const double tq = Seconds(sim, *qs), tc = Seconds(sim, *cs);
  const SE3 gq = sim.trajectory(qa).WorldFromCam(tq), gc = sim.trajectory(ca).WorldFromCam(tc);
  const SE3 q_from_c = gq.inverse() * gc;
  const Eigen::Matrix3d dR = e.query_from_candidate.rotation().toRotationMatrix().transpose() *
                             q_from_c.rotation().toRotationMatrix();
  c.rotation_error_deg = Eigen::AngleAxisd(dR).angle() * 180.0 / M_PI;
  const Eigen::Vector3d t_true = q_from_c.translation(), t_est = e.query_from_candidate.translation();
  c.baseline_m = t_true.norm();
  if (c.baseline_m >= 0.3 && t_est.norm() > 1e-9) {
    const double cosine = std::clamp(t_true.normalized().dot(t_est.normalized()), -1.0, 1.0);
    c.direction_error_deg = std::acos(cosine) * 180.0 / M_PI;
  }
  const sim::SampledView vq = truth.Sample(sim, gq, tq);
  const sim::ViewOverlap o = truth.Compare(vq, truth.Sample(sim, gc, tc));
  c.view_share = std::min(o.share_a, o.share_b);
  c.window_view_share = c.view_share;
  const auto& traj_c = sim.trajectory(ca);
  for (double dt = -2.0; dt <= 2.0 + 1e-9; dt += 0.5) {
    const double t = std::clamp(tc + dt, 0.0, traj_c.duration_s());
    const sim::ViewOverlap w = truth.Compare(vq, truth.Sample(sim, traj_c.WorldFromCam(t), t));
    c.window_view_share = std::max(c.window_view_share, std::min(w.share_a, w.share_b));
  }
  const auto scale_q = LocalVoScale(r.agents[qa], *qs), scale_c = LocalVoScale(r.agents[ca], *cs);
  if (scale_q && scale_c) c.scale_error = e.query_from_candidate.scale() * *scale_q / *scale_c - 1.0;
  if (scale_q) c.estimated_baseline_m = *scale_q * t_est.norm();
  c.wrong = c.rotation_error_deg > 10.0 || c.direction_error_deg > 30.0 || c.window_view_share < kMinViewShare;
  return c;
}

// RMSE over segments, each aligned on its own (a new segment starts a new VO frame), and
// the scale drift of the longest segment (5 m windows).
void ScoreSegments(const report::AgentRunResult& a, AgentScore* score) {
  double sum_sq = 0.0;
  size_t n = 0, longest = 0;
  EvalOptions options;
  options.scale_window_m = 5.0;
  for (const auto& [segment, t] : a.vo_segments) {
    if (t.size() < 3) continue;
    EvalReport rep;
    std::string error;
    if (!Evaluate({{a.name, a.ground_truth, t}}, options, &rep, &error)) continue;
    const AgentResult& r = rep.agents[0];
    sum_sq += r.ate_m.rmse * r.ate_m.rmse * static_cast<double>(r.matched);
    n += r.matched;
    score->vo_path_m += PathLengthM(r.gt_matched);
    if (r.matched > longest && r.scale_drift.windows.size() >= 2) {
      longest = r.matched;
      score->vo_scale_drift = r.scale_drift.max_over_min - 1.0;
      score->vo_first_window_scale = r.scale_drift.windows.front().scale;
    }
  }
  score->vo_ate_m = n ? std::sqrt(sum_sq / static_cast<double>(n)) : -1.0;
}

MapScore ScoreMap(const MapSummary& m, const report::RunResult& r, const std::vector<AgentScore>& agents) {
  MapScore s;
  s.id = m.id;
  s.keyframes = m.keyframes + m.anchored;
  std::vector<AgentInput> joint;
  double standalone = 0.0;
  for (size_t i = 0; i < r.agents.size(); ++i) {
    Trajectory in_map;
    for (const ServerKeyframePose& p : r.agents[i].server_keyframes) {
      if (p.map == m.id) in_map.push_back({p.stamp_ns, p.world_from_cam});
    }
    if (in_map.size() < 3) continue;
    s.agents.push_back(static_cast<int>(i));
    joint.push_back({r.agents[i].name, r.agents[i].ground_truth, in_map});
    standalone += agents[i].vo_ate_m;
  }
  if (joint.empty()) return s;
  s.mean_standalone_ate_m = standalone / static_cast<double>(joint.size());
  EvalReport rep;
  std::string error;
  if (!Evaluate(joint, EvalOptions{}, &rep, &error)) return s;
  s.joint_ate_m = rep.joint.ate_m.rmse;
  double lo = 1e300, hi = 0.0;
  for (const AgentResult& a : rep.agents) {
    s.own_ate_m.push_back(a.ate_m.rmse);
    s.joint_ate_per_agent_m.push_back(a.ate_joint_m.rmse);
    s.agent_scale.push_back(a.gt_from_est.scale());
    lo = std::min(lo, a.gt_from_est.scale());
    hi = std::max(hi, a.gt_from_est.scale());
  }
  s.scale_spread = hi / lo - 1.0;
  return s;
}

// Splits the agent's revisit links by ground truth (see AgentScore).
void ScoreRevisitLinks(const sim::Simulation& sim, const sim::OverlapTruth& truth, int agent,
                       const report::AgentRunResult& a, AgentScore* score) {
  const double gap_s = truth.options().revisit_gap_s;
  const auto& traj = sim.trajectory(agent);
  // A keyframe is in many links (a revisit links it to every early keyframe it shares
  // points with): ray-cast each keyframe's view once.
  std::map<std::int64_t, sim::SampledView> views;
  const auto view = [&](std::int64_t ns) -> const sim::SampledView& {
    auto it = views.find(ns);
    if (it == views.end()) {
      const double t = Seconds(sim, ns);
      it = views.emplace(ns, truth.Sample(sim, traj.WorldFromCam(t), t)).first;
    }
    return it->second;
  };
  for (const RevisitLink& l : a.revisit_links) {
    const double te = Seconds(sim, l.early_ns), tl = Seconds(sim, l.late_ns);
    if (tl - te < gap_s) continue;
    if (truth.MayShareSurface(view(l.early_ns), view(l.late_ns))) {
      ++score->true_revisit_links;
    } else {
      ++score->false_revisit_links;
    }
  }
  score->revisit_joined = score->true_revisit_links > 0;
}

}  // namespace

SceneScore ScoreScene(const sim::Simulation& sim, const sim::OverlapTruth& truth, const report::RunResult& r) {
  SceneScore s;
  // Agents' VO.
  for (size_t i = 0; i < r.agents.size(); ++i) {
    const report::AgentRunResult& a = r.agents[i];
    AgentScore as;
    as.name = a.name;
    as.path_m = truth.agents()[i].path_m;
    as.tracked_share = a.frames ? static_cast<double>(a.frames_tracked) / static_cast<double>(a.frames) : 0.0;
    as.segments = a.segments;
    as.relocalizations = a.relocalizations;
    ScoreSegments(a, &as);
    const double vo_path = as.vo_path_m > 0.0 ? as.vo_path_m : as.path_m;
    if (as.vo_ate_m >= 0 && vo_path > 0) as.vo_ate_path_pct = 100.0 * as.vo_ate_m / vo_path;
    as.revisits = truth.agents()[i].revisits;
    ScoreRevisitLinks(sim, truth, static_cast<int>(i), a, &as);
    if (as.revisits) {
      as.keyframes_from_revisit = 0;
      for (const auto& k : a.vo_keyframes) as.keyframes_from_revisit += Seconds(sim, k.stamp_ns) >= truth.agents()[i].first_revisit_s;
    }
    as.server_keyframes = a.server_keyframes.size();
    for (const ServerKeyframePose& p : a.server_keyframes) as.anchored_keyframes += !p.in_map;
    s.agents.push_back(as);
  }
  // Fusions and loops, in the order the server made them; which pairs they joined.
  std::map<MapId, MapId> parent;
  const std::function<MapId(MapId)> root = [&](MapId m) {
    auto it = parent.find(m);
    if (it == parent.end() || it->second == m) return m;
    return it->second = root(it->second);
  };
  std::map<int, std::vector<MapId>> agent_maps;
  for (const ServerEvent& e : r.events) {
    if (e.kind == ServerEvent::Kind::kNewMap) agent_maps[AgentIndex(r, e.agent)].push_back(e.map);
  }
  for (const sim::PairTruth& p : truth.pairs()) s.pairs.push_back({p});
  for (const ServerEvent& e : r.events) {
    if (e.kind == ServerEvent::Kind::kLoop) {
      s.loops.push_back(Check(sim, truth, r, e));
      const int a = AgentIndex(r, e.agent);
      if (a >= 0) ++s.agents[a].loops;
      continue;
    }
    if (e.kind != ServerEvent::Kind::kFusion) continue;
    s.fusions.push_back(Check(sim, truth, r, e));
    parent[root(e.other_map)] = root(e.map);
    for (PairScore& p : s.pairs) {
      if (p.fused) continue;
      for (const MapId ma : agent_maps[p.truth.a]) {
        for (const MapId mb : agent_maps[p.truth.b]) p.fused = p.fused || root(ma) == root(mb);
      }
      if (!p.fused) continue;
      p.fused_at_s = Seconds(sim, e.stamp_ns);
      if (p.truth.first_s >= 0) p.seconds_to_fusion = std::max(0.0, p.fused_at_s - p.truth.first_s);
    }
  }
  for (const PairScore& p : s.pairs) {
    if (!p.truth.qualifies) continue;
    ++s.qualifying_pairs;
    s.qualifying_fused += p.fused;
  }
  for (const DetectionCheck& c : s.fusions) s.false_fusions += c.wrong;
  for (const DetectionCheck& c : s.loops) s.false_loops += c.wrong;
  for (const MapSummary& m : r.maps) {
    MapScore ms = ScoreMap(m, r, s.agents);
    if (ms.agents.size() >= 2 && ms.joint_ate_m >= 0 && ms.mean_standalone_ate_m > 0) {
      s.worst_joint_ratio = std::max(s.worst_joint_ratio, ms.joint_ate_m / ms.mean_standalone_ate_m);
      s.worst_scale_spread = std::max(s.worst_scale_spread, ms.scale_spread);
    }
    s.maps.push_back(std::move(ms));
  }
  return s;
}

}  // namespace ccm::bench
