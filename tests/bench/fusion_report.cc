#include "tests/bench/fusion_report.h"

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <map>

namespace ccm::bench {
namespace {

std::string Format(const char* fmt, ...) {
  char buf[1024];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof(buf), fmt, args);
  va_end(args);
  return buf;
}

double Median(std::vector<double> v) {
  if (v.empty()) return -1.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::string Percent(int n, int d) { return d ? Format("%d/%d (%.0f %%)", n, d, 100.0 * n / d) : std::string("-"); }

// A segment too short for two 5 m windows has no scale drift (the scorer leaves -1).
std::string ScaleDrift(double drift) { return drift < 0.0 ? std::string("n/a") : Format("%.0f %%", 100.0 * drift); }
std::string FirstWindowScale(double scale) { return scale < 0.0 ? std::string("n/a") : Format("%.2f", scale); }

std::string PairLine(const PairScore& p) {
  const sim::PairTruth& t = p.truth;
  std::string s = Format("%d-%d %s", t.a, t.b, t.kind.c_str());
  if (t.overlaps) s += Format(" %.1f/%.1f s %.0f deg", t.seconds_a, t.seconds_b, t.median_angle_deg);
  if (p.fused) s += Format(" -> fused at %.1f s", p.fused_at_s);
  if (p.fused && p.seconds_to_fusion >= 0) s += Format(" (+%.1f s)", p.seconds_to_fusion);
  if (t.qualifies && !p.fused) s += " -> NOT FUSED";
  return s;
}

std::string EventLine(const char* kind, const DetectionCheck& c) {
  return Format("  %s %u/%u: rotation error %.1f deg, direction error %.1f deg (baseline %.2f m, estimated %.2f m), "
                "scale error %+.1f %%, view share %.2f (window %.2f)%s; %s\n",
                kind, c.event.query.agent(), c.event.candidate.agent(), c.rotation_error_deg, c.direction_error_deg,
                c.baseline_m, c.estimated_baseline_m, 100.0 * c.scale_error, c.view_share, c.window_view_share, c.wrong ? " WRONG" : "", c.event.detail.c_str());
}

}  // namespace

std::string SceneBlock(const SceneResult& r, bool events) {
  std::string s = Format("seed %llu: %s", static_cast<unsigned long long>(r.scene.seed), r.scene.Summary().c_str());
  if (!r.error.empty()) return s + "\n  error: " + r.error + "\n";
  const SceneScore& sc = r.score;
  s += Format("  [%lld frames, %.0f s; %d global BAs, %.1f s, longest %.1f s at %d keyframes]\n",
              static_cast<long long>(r.frames), r.wall_s, r.global_bas, r.global_ba_total_s, r.global_ba_max_s,
              r.global_ba_max_keyframes);
  for (const PairScore& p : sc.pairs) {
    if (p.truth.overlaps || p.fused) s += "  pair " + PairLine(p) + "\n";
  }
  s += Format("  fusions %zu (%d wrong), loops %zu (%d wrong), maps %zu", sc.fusions.size(), sc.false_fusions,
              sc.loops.size(), sc.false_loops, sc.maps.size());
  if (sc.worst_joint_ratio >= 0) {
    s += Format(", worst fused map: joint ATE %.2fx its agents' VO, scale spread %.1f %%", sc.worst_joint_ratio,
                100.0 * sc.worst_scale_spread);
  }
  s += "\n";
  s += Format("  place recognition: %lld queries, %lld fusion candidates, stopped at:", static_cast<long long>(r.place.queries),
              static_cast<long long>(r.place.match_candidates));
  for (int i = 0; i < kNumVerificationStages; ++i) {
    if (r.place.fusion_stopped_at[i] > 0) {
      s += Format(" %s %lld", VerificationStageName(static_cast<VerificationStage>(i)),
                  static_cast<long long>(r.place.fusion_stopped_at[i]));
    }
  }
  s += Format("; inconsistent %lld\n", static_cast<long long>(r.place.inconsistent));
  for (const MissedPairDiagnosis& d : r.missed) s += FormatDiagnosis(d);
  if (events) {
    for (const DetectionCheck& c : sc.fusions) s += EventLine("fusion", c);
    for (const DetectionCheck& c : sc.loops) s += EventLine("loop", c);
    for (const std::string& d : r.global_ba_details) s += "  global BA: " + d + "\n";
    for (const MapScore& m : sc.maps) {
      if (m.agents.size() < 2) continue;
      s += Format("  map %u:%llu: %zu keyframes, joint ATE %.3f m;", m.id.agent(), static_cast<unsigned long long>(m.id.counter()), m.keyframes, m.joint_ate_m);
      for (size_t i = 0; i < m.own_ate_m.size(); ++i) {
        s += Format(" agent%d own %.3f / joint %.3f m, scale %.3f;", m.agents[i], m.own_ate_m[i],
                    m.joint_ate_per_agent_m[i], m.agent_scale[i]);
      }
      s += "\n";
    }
  }
  for (const DetectionCheck& c : sc.fusions) {
    if (c.wrong && !events) {
      s += Format("  WRONG fusion: agents %u/%u, rotation error %.1f deg, direction error %.1f deg, view share %.2f (window %.2f)\n",
                  c.event.query.agent(), c.event.candidate.agent(), c.rotation_error_deg, c.direction_error_deg,
                  c.view_share, c.window_view_share);
    }
  }
  for (const AgentScore& a : sc.agents) {
    s += Format("  %s: tracked %.0f %%, %d segment(s), %lld reloc, VO ATE %.3f m (%.2f %% of the %.0f m its keyframes span; flight %.0f m), scale drift %s "
                "(first 5 m at %s)%s, %d loop(s), revisit links %d (%d false), %s%zu server keyframes (%zu anchored)\n",
                a.name.c_str(), 100.0 * a.tracked_share, a.segments, static_cast<long long>(a.relocalizations),
                a.vo_ate_m, a.vo_ate_path_pct, a.vo_path_m, a.path_m, ScaleDrift(a.vo_scale_drift).c_str(),
                FirstWindowScale(a.vo_first_window_scale).c_str(),
                a.revisits ? (a.revisit_joined ? ", revisits (joined)" : ", revisits (not joined)") : "", a.loops,
                a.true_revisit_links, a.false_revisit_links,
                a.revisits ? Format("%d own keyframes from its first revisit on, ", a.keyframes_from_revisit).c_str() : "",
                a.server_keyframes, a.anchored_keyframes);
  }
  return s;
}

nlohmann::json SceneJson(const SceneResult& r) {
  nlohmann::json j = {{"seed", r.scene.seed}, {"summary", r.scene.Summary()}, {"layout", sim::SceneLayoutName(r.scene.layout)},
                      {"agents", r.scene.num_agents}, {"camera", r.scene.camera}, {"textures", r.scene.texture_profile},
                      {"rate_hz", r.scene.rate_hz}, {"motion_blur", r.scene.motion_blur}, {"frames", r.frames},
                      {"wall_s", r.wall_s}, {"place_recognition_ms", r.place_recognition_ms}, {"error", r.error},
                      {"global_ba", {{"runs", r.global_bas}, {"total_s", r.global_ba_total_s}, {"max_s", r.global_ba_max_s},
                                     {"max_keyframes", r.global_ba_max_keyframes}}}};
  const SceneScore& sc = r.score;
  for (const PairScore& p : sc.pairs) {
    const sim::PairTruth& t = p.truth;
    j["pairs"].push_back({{"a", t.a}, {"b", t.b}, {"kind", t.kind}, {"overlaps", t.overlaps}, {"qualifies", t.qualifies},
                          {"first_s", t.first_s}, {"seconds_a", t.seconds_a}, {"seconds_b", t.seconds_b},
                          {"angle_deg", t.median_angle_deg}, {"fused", p.fused}, {"fused_at_s", p.fused_at_s},
                          {"seconds_to_fusion", p.seconds_to_fusion}});
  }
  for (const auto* list : {&sc.fusions, &sc.loops}) {
    for (const DetectionCheck& c : *list) {
      j[list == &sc.fusions ? "fusions" : "loops"].push_back(
          {{"query_agent", c.event.query.agent()}, {"candidate_agent", c.event.candidate.agent()},
           {"rotation_error_deg", c.rotation_error_deg}, {"direction_error_deg", c.direction_error_deg},
           {"view_share", c.view_share}, {"window_view_share", c.window_view_share}, {"wrong", c.wrong}});
    }
  }
  for (const MapScore& m : sc.maps) {
    j["maps"].push_back({{"agents", m.agents}, {"keyframes", m.keyframes}, {"joint_ate_m", m.joint_ate_m},
                         {"mean_standalone_ate_m", m.mean_standalone_ate_m}, {"scale_spread", m.scale_spread},
                         {"own_ate_m", m.own_ate_m}, {"agent_scale", m.agent_scale}});
  }
  for (const AgentScore& a : sc.agents) {
    j["agent_vo"].push_back({{"name", a.name}, {"path_m", a.path_m}, {"vo_path_m", a.vo_path_m}, {"tracked", a.tracked_share},
                             {"segments", a.segments}, {"relocalizations", a.relocalizations}, {"ate_m", a.vo_ate_m},
                             {"ate_path_pct", a.vo_ate_path_pct}, {"scale_drift", a.vo_scale_drift},
                             {"first_window_scale", a.vo_first_window_scale}, {"revisits", a.revisits}, {"loops", a.loops},
                             {"revisit_joined", a.revisit_joined}, {"revisit_links", a.true_revisit_links},
                             {"false_revisit_links", a.false_revisit_links}, {"keyframes_from_revisit", a.keyframes_from_revisit},
                             {"revisit_held", a.revisit_held()}, {"server_keyframes", a.server_keyframes},
                             {"anchored_keyframes", a.anchored_keyframes}});
  }
  return j;
}

std::string Report(const std::vector<SceneResult>& results) {
  std::string s = "\n| seed | scene | qualifying pairs fused | median s to fusion | false fusions | loops (false) | "
                  "revisiting agents with a loop | maps | joint / VO ATE | scale spread | wall s |\n"
                  "|---|---|---|---|---|---|---|---|---|---|---|\n";
  int q = 0, qf = 0, ff = 0, fl = 0, rev = 0, rev_loop = 0, rev_joined = 0, rev_held = 0, false_links = 0, fused_scenes = 0, good_ate = 0, good_scale = 0;
  int fused_parts = 0, good_parts = 0;
  int agents = 0, good_vo = 0, tracked_full = 0;
  std::size_t full_keyframes = 0, anchored_keyframes = 0;
  double vo_path_pct_sum = 0.0;
  std::vector<double> to_fusion, pr_ms;
  std::map<std::string, std::pair<int, int>> by_kind;  // measured kind -> (fused, qualifying)
  for (const SceneResult& r : results) {
    if (!r.error.empty()) {
      s += Format("| %llu | error: %s |\n", static_cast<unsigned long long>(r.scene.seed), r.error.c_str());
      continue;
    }
    const SceneScore& sc = r.score;
    std::vector<double> scene_times;
    int scene_rev = 0, scene_rev_loop = 0;
    for (const PairScore& p : sc.pairs) {
      if (!p.truth.qualifies) continue;
      auto& k = by_kind[p.truth.kind];
      ++k.second;
      k.first += p.fused;
      if (p.fused && p.seconds_to_fusion >= 0) scene_times.push_back(p.seconds_to_fusion), to_fusion.push_back(p.seconds_to_fusion);
    }
    for (const AgentScore& a : sc.agents) {
      scene_rev += a.revisits;
      scene_rev_loop += a.revisits && a.loops > 0;
      rev_joined += a.revisits && a.revisit_joined;
      rev_held += a.revisit_held();
      false_links += a.false_revisit_links;
      ++agents;
      good_vo += a.vo_ate_path_pct >= 0 && a.vo_ate_path_pct <= 1.0 && a.tracked_share > 0.9;
      tracked_full += a.tracked_share >= 0.99;
      full_keyframes += a.server_keyframes - a.anchored_keyframes;
      anchored_keyframes += a.anchored_keyframes;
      vo_path_pct_sum += std::max(0.0, a.vo_ate_path_pct);
    }
    q += sc.qualifying_pairs, qf += sc.qualifying_fused, ff += sc.false_fusions, fl += sc.false_loops;
    rev += scene_rev, rev_loop += scene_rev_loop;
    for (const MapScore& m : sc.maps) {
      if (m.agents.size() < 2 || m.own_ate_m.size() != m.agents.size()) continue;
      for (size_t i = 0; i < m.agents.size(); ++i) {
        const double vo = sc.agents[static_cast<size_t>(m.agents[i])].vo_ate_m;
        if (vo <= 0) continue;
        ++fused_parts;
        good_parts += m.own_ate_m[i] <= vo;
      }
    }
    if (sc.worst_joint_ratio >= 0) {
      ++fused_scenes;
      good_ate += sc.worst_joint_ratio <= 1.0;
      good_scale += sc.worst_scale_spread <= 0.02;
    }
    pr_ms.push_back(r.place_recognition_ms);
    s += Format("| %llu | %s | %s | %.1f | %d | %zu (%d) | %d/%d | %zu | %s | %s | %.0f |\n",
                static_cast<unsigned long long>(r.scene.seed), r.scene.Summary().c_str(),
                Percent(sc.qualifying_fused, sc.qualifying_pairs).c_str(), Median(scene_times), sc.false_fusions,
                sc.loops.size(), sc.false_loops, scene_rev_loop, scene_rev, sc.maps.size(),
                sc.worst_joint_ratio >= 0 ? Format("%.2f", sc.worst_joint_ratio).c_str() : "-",
                sc.worst_joint_ratio >= 0 ? Format("%.1f %%", 100.0 * sc.worst_scale_spread).c_str() : "-", r.wall_s);
  }
  s += "\n| seed | agent | path m | its keyframes span m | tracked | segments | relocalizations | VO ATE m | % of the span | scale drift | first 5 m | revisits | loops | revisit links (false) |\n"
       "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const SceneResult& r : results) {
    for (const AgentScore& a : r.score.agents) {
      s += Format("| %llu | %s | %.0f | %.0f | %.0f %% | %d | %lld | %.3f | %.2f | %s | %s | %s | %d | %d (%d) |\n",
                  static_cast<unsigned long long>(r.scene.seed), a.name.c_str(), a.path_m, a.vo_path_m, 100.0 * a.tracked_share,
                  a.segments, static_cast<long long>(a.relocalizations), a.vo_ate_m, a.vo_ate_path_pct,
                  ScaleDrift(a.vo_scale_drift).c_str(), FirstWindowScale(a.vo_first_window_scale).c_str(),
                  a.revisits ? "yes" : "no", a.loops,
                  a.true_revisit_links, a.false_revisit_links);
    }
  }
  s += "\nRecall by measured overlap kind (qualifying pairs: >= 3 s each within 45 deg):\n";
  for (const auto& [kind, n] : by_kind) s += "  " + kind + ": " + Percent(n.first, n.second) + "\n";
  s += "\nTotals (goals of issue 27 in brackets):\n";
  s += "  qualifying pairs fused: " + Percent(qf, q) + " [>= 90 %]\n";
  s += Format("  false fusions: %d [0]; false loops: %d\n", ff, fl);
  s += Format("  median seconds of flight from the first overlap to the fusion: %.1f [<= 5]\n", Median(to_fusion));
  s += "  revisiting agents with at least one loop: " + Percent(rev_loop, rev) + " [all]\n";
  s += "  revisiting agents whose revisit the map holds once (a true revisit link): " + Percent(rev_joined, rev) +
       Format("; false revisit links: %d\n", false_links);
  s += "  revisiting agents whose revisit the map holds (a loop, a true revisit link, or every revisit flown in the map it had:\n"
       "    no keyframe of its own from the first revisit on, tracking >= 99 %): " + Percent(rev_held, rev) + "\n";
  s += "  scenes whose fused maps are at least as accurate as their agents' VO: " + Percent(good_ate, fused_scenes) +
       " [>= 90 %]\n";
  // Each agent's part of a fused map aligned on its own: what fusing did to the map its agent
  // gets back, apart from how the parts agree with each other (the joint ATE above also pays
  // for each part's own scale drift away from the overlap, which one Sim(3) cannot absorb).
  s += "  agents whose part of a fused map, aligned on its own, is at least as accurate as their VO: " +
       Percent(good_parts, fused_parts) + "\n";
  s += "  scenes whose fused maps agree in scale within 2 %: " + Percent(good_scale, fused_scenes) + "\n";
  s += "  agents whose VO is within 1 % of its path (and tracks > 90 %): " + Percent(good_vo, agents) + " [>= 95 %]\n";
  s += "  agents tracking >= 99 % of their frames: " + Percent(tracked_full, agents) + "\n";
  s += Format("  agents' VO ATE, mean %% of the path: %.2f\n", agents ? vo_path_pct_sum / agents : 0.0);
  s += Format("  server keyframes of all agents: %zu in full, %zu anchors (pose only)\n", full_keyframes,
              anchored_keyframes);
  s += Format("  place recognition per keyframe (mean per scene, median over scenes): %.2f ms [<= 5]\n", Median(pr_ms));
  return s;
}

}  // namespace ccm::bench
