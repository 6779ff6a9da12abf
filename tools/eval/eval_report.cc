#include "eval_report.h"

#include <cstdarg>
#include <cstdio>

namespace ccm::tools {
namespace {

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"count", s.count}, {"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median},
          {"std", s.std},     {"min", s.min},   {"max", s.max},   {"sse", s.sse}};
}

nlohmann::json AlignmentJson(const Sim3& s) {
  const Eigen::Quaterniond& q = s.rotation();
  const Eigen::Vector3d& t = s.translation();
  return {{"scale", s.scale()},
          {"rotation_xyzw", {q.x(), q.y(), q.z(), q.w()}},
          {"translation", {t.x(), t.y(), t.z()}}};
}

std::string Line(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string Line(const char* fmt, ...) {
  char buffer[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buffer, sizeof(buffer), fmt, args);
  va_end(args);
  return buffer;
}

std::string StatsColumns(const ErrorStats& s) {
  return Line("%9.4f %8.4f %8.4f %8.4f %8.4f %8.4f", s.rmse, s.mean, s.median, s.std, s.min, s.max);
}

}  // namespace

std::string FormatTable(const EvalReport& report, const EvalOptions& options) {
  std::string out;
  const char* unit = options.rpe.unit == RpeDeltaUnit::kFrames ? "frames" : "m";
  out += Line("alignment %s%s, association |dt| <= %.4f s, RPE delta %g %s%s\n",
              ToString(options.alignment),
              options.align_first_n > 0 ? (" (first " + std::to_string(options.align_first_n) +
                                           " pairs)").c_str() : "",
              options.association.max_dt_s, options.rpe.delta, unit,
              options.rpe.all_pairs ? " (all pairs)" : "");
  out += "\nATE [m] (translation, each agent aligned on its own; 'joint rmse' = under the one\n"
         "alignment shared by all agents)\n";
  out += Line("%-16s %7s %7s %7s %8s %9s %8s %8s %8s %8s %8s %11s\n", "agent", "gt", "est",
              "matched", "scale", "rmse", "mean", "median", "std", "min", "max", "joint rmse");
  for (const AgentResult& a : report.agents) {
    out += Line("%-16s %7zu %7zu %7zu %8.4f ", a.name.c_str(), a.gt_poses, a.est_poses, a.matched,
                a.gt_from_est.scale()) +
           StatsColumns(a.ate_m) + Line(" %11.4f\n", a.ate_joint_m.rmse);
  }
  const JointResult& j = report.joint;
  out += Line("%-16s %7s %7s %7zu %8.4f ", "JOINT", "", "", j.matched, j.gt_from_est.scale()) +
         StatsColumns(j.ate_m) + "\n";
  out += Line("\nRPE (translation [m], rotation [deg])\n%-16s %7s %9s %9s %9s %9s %9s\n", "agent",
              "pairs", "t rmse", "t mean", "t max", "r rmse", "r mean");
  auto rpe_row = [&](const std::string& name, const ErrorStats& t, const ErrorStats& r) {
    out += Line("%-16s %7zu %9.4f %9.4f %9.4f %9.4f %9.4f\n", name.c_str(), t.count, t.rmse,
                t.mean, t.max, r.rmse, r.mean);
  };
  for (const AgentResult& a : report.agents) rpe_row(a.name, a.rpe.translation_m, a.rpe.rotation_deg);
  rpe_row("JOINT", j.rpe_translation_m, j.rpe_rotation_deg);
  if (options.scale_window_m > 0.0) {
    out += Line("\nScale drift (gt / est spread per %g m of path, each agent's alignment = 1)\n", options.scale_window_m);
    out += Line("%-16s %7s %8s %8s %8s %8s %8s  %s\n", "agent", "windows", "first", "last", "min", "max",
                "max/min", "per window");
    for (const AgentResult& a : report.agents) {
      const auto& w = a.scale_drift.windows;
      if (w.empty()) {
        out += Line("%-16s %7d (path shorter than one window)\n", a.name.c_str(), 0);
        continue;
      }
      std::string each;
      for (const ScaleWindow& x : w) each += Line(" %.2f", x.scale);
      out += Line("%-16s %7zu %8.3f %8.3f %8.3f %8.3f %8.3f ", a.name.c_str(), w.size(), w.front().scale,
                  w.back().scale, a.scale_drift.min_scale, a.scale_drift.max_scale, a.scale_drift.max_over_min) +
             each + "\n";
    }
  }
  return out;
}

nlohmann::json ToJson(const EvalReport& report, const EvalOptions& options,
                      const std::vector<InputFiles>& files) {
  nlohmann::json agents = nlohmann::json::array();
  for (size_t i = 0; i < report.agents.size(); ++i) {
    const AgentResult& a = report.agents[i];
    agents.push_back({{"name", a.name},
                      {"gt_file", i < files.size() ? files[i].gt_path : ""},
                      {"est_file", i < files.size() ? files[i].est_path : ""},
                      {"gt_poses", a.gt_poses},
                      {"est_poses", a.est_poses},
                      {"matched", a.matched},
                      {"alignment", AlignmentJson(a.gt_from_est)},
                      {"ate_m", StatsJson(a.ate_m)},
                      {"ate_joint_m", StatsJson(a.ate_joint_m)},
                      {"rpe_translation_m", StatsJson(a.rpe.translation_m)},
                      {"rpe_rotation_deg", StatsJson(a.rpe.rotation_deg)}});
    if (options.scale_window_m > 0.0) {
      nlohmann::json windows = nlohmann::json::array();
      for (const ScaleWindow& w : a.scale_drift.windows) {
        windows.push_back({{"first", w.first}, {"last", w.last}, {"gt_path_m", w.gt_path_m}, {"scale", w.scale}});
      }
      agents.back()["scale_drift"] = {{"window_m", options.scale_window_m},
                                      {"max_over_min", a.scale_drift.max_over_min},
                                      {"windows", windows}};
    }
  }
  const JointResult& j = report.joint;
  return {{"tool", "ccm_eval"},
          {"schema_version", 1},
          {"options",
           {{"align", ToString(options.alignment)},
            {"n_align", options.align_first_n},
            {"max_dt_s", options.association.max_dt_s},
            {"t_offset_s", options.association.est_offset_s},
            {"rpe",
             {{"delta", options.rpe.delta},
              {"unit", options.rpe.unit == RpeDeltaUnit::kFrames ? "frames" : "m"},
              {"all_pairs", options.rpe.all_pairs}}}}},
          {"agents", agents},
          {"joint",
           {{"matched", j.matched},
            {"alignment", AlignmentJson(j.gt_from_est)},
            {"ate_m", StatsJson(j.ate_m)},
            {"rpe_translation_m", StatsJson(j.rpe_translation_m)},
            {"rpe_rotation_deg", StatsJson(j.rpe_rotation_deg)}}}};
}

}  // namespace ccm::tools
