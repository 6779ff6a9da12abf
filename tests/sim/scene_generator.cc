#include "tests/sim/scene_generator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <Eigen/Core>

#include "tests/sim/scene_layout.h"
#include "tests/sim/sim_random.h"

namespace ccm::sim {

const char* SceneLayoutName(SceneLayout layout) {
  switch (layout) {
    case SceneLayout::kRoom: return "room";
    case SceneLayout::kHall: return "hall";
    case SceneLayout::kYard: return "yard";
    case SceneLayout::kCorridor: return "corridor";
  }
  return "?";
}

const char* PlannedOverlapName(PlannedOverlapKind kind) {
  switch (kind) {
    case PlannedOverlapKind::kNone: return "none";
    case PlannedOverlapKind::kSame: return "same";
    case PlannedOverlapKind::kOblique: return "oblique";
    case PlannedOverlapKind::kBrief: return "brief";
    case PlannedOverlapKind::kLong: return "long";
  }
  return "?";
}

std::string SceneGeneratorOptions::Validate() const {
  if (min_agents < 2 || max_agents > kMaxGeneratedAgents || min_agents > max_agents)
    return "agents must satisfy 2 <= min <= max <= " + std::to_string(kMaxGeneratedAgents);
  if (!(min_duration_s >= 10.0 && max_duration_s >= min_duration_s && max_duration_s <= 600.0))
    return "durations must satisfy 10 <= min <= max <= 600 s";
  return {};
}

std::string GeneratedScene::Summary() const {
  int overlaps = 0;
  for (const PlannedOverlap& p : plan) overlaps += p.kind != PlannedOverlapKind::kNone;
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%s, %d agents, %d planned overlaps, %s textures, %s camera at %.0f Hz%s",
                SceneLayoutName(layout), num_agents, overlaps, texture_profile.c_str(), camera.c_str(), rate_hz,
                motion_blur ? ", motion blur" : "");
  return buf;
}

namespace {

const char* StyleName(int s) {
  static const char* kNames[] = {"rich", "mixed", "weak"};
  return kNames[std::clamp(s, 0, 2)];
}

struct CameraChoice {
  std::string name, yaml;  // yaml: empty = the EuRoC default
};

CameraChoice PickCamera(Rng* rng, bool allow_fisheye) {
  const int kind = rng->Pick({0.3, 0.35, 0.2, allow_fisheye ? 0.15 : 0.0});
  char buf[320];
  if (kind == 0) return {"euroc", ""};
  if (kind == 1) {  // VGA pinhole, 60-80 deg across
    const double f = rng->Uniform(380.0, 560.0);
    std::snprintf(buf, sizeof(buf),
                  "camera: {model: pinhole-radtan, width: 640, height: 480, fx: %.1f, fy: %.1f, cx: %.1f, cy: %.1f, "
                  "distortion: [%.4f, %.4f, 0, 0]}\n",
                  f, f * rng->Uniform(0.995, 1.005), rng->Uniform(310.0, 330.0), rng->Uniform(230.0, 250.0),
                  rng->Uniform(-0.12, 0.02), rng->Uniform(0.0, 0.05));
    return {"vga", buf};
  }
  if (kind == 2) {  // wide 848x480, 90-105 deg across
    const double f = rng->Uniform(330.0, 420.0);
    std::snprintf(buf, sizeof(buf),
                  "camera: {model: pinhole-radtan, width: 848, height: 480, fx: %.1f, fy: %.1f, cx: %.1f, cy: %.1f, "
                  "distortion: [%.4f, %.4f, 0, 0]}\n",
                  f, f, rng->Uniform(414.0, 434.0), rng->Uniform(230.0, 250.0), rng->Uniform(-0.2, -0.05),
                  rng->Uniform(0.0, 0.04));
    return {"wide", buf};
  }
  return {"fisheye", "camera: {model: fisheye-equidistant}\n"};
}

int PickAgents(Rng* rng, const SceneGeneratorOptions& o) {
  // Small teams are commoner (and cheaper to replay); every size in range occurs.
  double total = 0.0;
  for (int n = o.min_agents; n <= o.max_agents; ++n) total += n <= 4 ? 1.0 : 0.3;
  double x = rng->Uniform() * total;
  for (int n = o.min_agents; n < o.max_agents; ++n) {
    if ((x -= n <= 4 ? 1.0 : 0.3) < 0.0) return n;
  }
  return o.max_agents;
}

SceneLayout PickLayout(Rng* rng, int agents) {
  if (agents <= 3) return static_cast<SceneLayout>(rng->Pick({0.28, 0.3, 0.17, 0.25}));
  if (agents == 4) return static_cast<SceneLayout>(rng->Pick({0.12, 0.4, 0.33, 0.15}));
  return static_cast<SceneLayout>(rng->Pick({0.0, 0.5, 0.5, 0.0}));
}

PlannedOverlapKind PickOverlap(Rng* rng) {
  return static_cast<PlannedOverlapKind>(rng->Pick({0.15, 0.28, 0.25, 0.14, 0.18}));
}

void WriteAgentYaml(std::ostringstream& y, const std::string& name, const FlightPlan& f, double rate_hz,
                    double duration_s) {
  char buf[256];
  std::snprintf(buf, sizeof(buf),
                "  - name: %s\n    rate_hz: %.0f\n    duration_s: %.1f\n    speed_mps: [%.2f, %.2f]\n"
                "    speed_period_s: %.1f\n    pitch_deg: %.1f\n    wobble_deg: %.1f\n    look_ahead_m: %.2f\n"
                "    waypoints: [",
                name.c_str(), rate_hz, duration_s, f.min_speed, f.max_speed, f.speed_period, f.pitch_deg, f.wobble_deg,
                f.look_ahead_m);
  y << buf;
  for (size_t i = 0; i < f.waypoints.size(); ++i) {
    const FlightWaypoint& w = f.waypoints[i];
    std::snprintf(buf, sizeof(buf), "%s[%.3f, %.3f, %.3f, %.1f]", i ? ", " : "", w.p.x(), w.p.y(), w.p.z(), w.yaw_deg);
    y << buf;
  }
  y << "]\n";
}

}  // namespace

GeneratedScene GenerateScene(std::uint64_t seed, const SceneGeneratorOptions& options) {
  Rng rng(HashCombine(seed, StringHash("scene-generator")));
  GeneratedScene g;
  g.seed = seed;
  g.num_agents = PickAgents(&rng, options);
  g.layout = PickLayout(&rng, g.num_agents);
  const int profile = rng.Pick({0.3, 0.45, 0.25});
  g.texture_profile = StyleName(profile);
  const CameraChoice camera = PickCamera(&rng, options.allow_fisheye);
  g.camera = camera.name;
  g.rate_hz = std::vector<double>{10.0, 15.0, 20.0}[rng.Pick({0.5, 0.3, 0.2})];
  g.motion_blur = options.allow_motion_blur && rng.Uniform() < 0.25;

  SceneBuilder builder(g.layout, g.num_agents, profile, &rng);
  // Neighbouring cells get a planned overlap each; at least one pair overlaps.
  std::vector<std::pair<int, int>> pairs = builder.NeighbourPairs();
  std::vector<PlannedOverlapKind> kinds;
  bool any = false;
  for (size_t i = 0; i < pairs.size(); ++i) {
    kinds.push_back(PickOverlap(&rng));
    any = any || kinds.back() != PlannedOverlapKind::kNone;
  }
  if (!any) kinds[rng.Int(0, static_cast<int>(kinds.size()) - 1)] = PlannedOverlapKind::kSame;
  for (size_t i = 0; i < pairs.size(); ++i) {
    PlannedOverlap p;
    p.agent_a = pairs[i].first;
    p.agent_b = pairs[i].second;
    p.kind = kinds[i];
    if (p.kind != PlannedOverlapKind::kNone) builder.PlanSharedTarget(&p);
    g.plan.push_back(p);
  }
  const double duration = rng.Uniform(options.min_duration_s, options.max_duration_s);
  builder.BuildFlights(duration);
  builder.AddFillerObjects();
  for (PlannedOverlap& p : g.plan) {
    p.flown = p.kind != PlannedOverlapKind::kNone && builder.arcs_flown(p.agent_a) && builder.arcs_flown(p.agent_b);
  }

  std::ostringstream y;
  char buf[256];
  std::snprintf(buf, sizeof(buf), "name: gen-%llu\ndescription: \"generated scene (seed %llu), ",
                static_cast<unsigned long long>(seed), static_cast<unsigned long long>(seed));
  y << buf << g.Summary() << "\"\n";
  std::snprintf(buf, sizeof(buf), "seed: %llu\ntexel_m: %.4f\nbackground_grey: %.0f\n",
                static_cast<unsigned long long>(HashMix(seed) % 1000000007ull), builder.texel_m(),
                builder.background_grey());
  y << buf << camera.yaml;
  const double exposure_variation = rng.Uniform(0.05, 0.35);
  std::snprintf(buf, sizeof(buf), "exposure: {variation: %.3f, period_s: %.1f}\n", exposure_variation,
                rng.Uniform(6.0, 30.0));
  y << buf;
  if (g.motion_blur) {
    std::snprintf(buf, sizeof(buf), "render: {motion_blur_samples: 3, exposure_time_s: %.4f}\n",
                  rng.Uniform(0.004, 0.015));
    y << buf;
  }
  y << "objects:\n";
  for (const std::string& o : builder.objects_yaml()) y << "  - " << o << "\n";
  y << "agents:\n";
  for (int a = 0; a < g.num_agents; ++a) {
    WriteAgentYaml(y, "agent" + std::to_string(a), builder.flight(a), g.rate_hz, builder.duration_s());
  }
  g.yaml = y.str();
  return g;
}

std::optional<std::string> GeneratedScenarioYaml(const std::string& name) {
  // "gen:SEED" or "gen:SEED:MAX_AGENTS": bench_fusion --max-agents 4 draws other scenes than
  // the default 8, and a diagnosis must fly the scene the benchmark flew.
  if (name.rfind("gen:", 0) != 0) return std::nullopt;
  const auto decimal = [](const std::string& text, std::uint64_t* value) {
    // At most 19 digits: every such number fits in 64 bits (stoull would throw beyond).
    if (text.empty() || text.size() > 19 || text.find_first_not_of("0123456789") != std::string::npos) return false;
    *value = std::stoull(text);
    return true;
  };
  const std::string rest = name.substr(4);
  const size_t colon = rest.find(':');
  std::uint64_t seed = 0, max_agents = 0;
  if (!decimal(rest.substr(0, colon), &seed)) return std::nullopt;
  SceneGeneratorOptions options;
  if (colon != std::string::npos) {
    if (!decimal(rest.substr(colon + 1), &max_agents) || max_agents > static_cast<std::uint64_t>(kMaxGeneratedAgents)) {
      return std::nullopt;
    }
    options.max_agents = static_cast<int>(max_agents);
    if (!options.Validate().empty()) return std::nullopt;
  }
  return GenerateScene(seed, options).yaml;
}

}  // namespace ccm::sim
