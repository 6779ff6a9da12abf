// Random multi-agent scenes for benchmarks: from a seed, a scenario (YAML of docs/simulator.md)
// with a layout (room, hall, yard, corridor), objects, a texture profile (rich, mixed, weak),
// a camera, exposure drift and motion blur, and 2-8 agents (up to 16 when asked for: a team-scale
// hall or yard of 3-4 rows of cells) flying loops in cells of the
// layout at their own heights and speeds. Neighbouring agents get an overlap of a planned
// kind: both orbit a shared target object, viewing it from the same direction or from
// directions 30-60 deg apart, for a brief (2-3 s) or a long time, or they get none.
// The plan says what was intended; what agents really saw in common is measured from the
// simulator's ground truth (overlap_truth.h). Same seed + options => the same YAML.
// Use: GenerateScene(seed).yaml, or the scenario name "gen:SEED" (or
// "gen:SEED:MAX_AGENTS") wherever a scenario is read.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace ccm::sim {

enum class SceneLayout { kRoom = 0, kHall = 1, kYard = 2, kCorridor = 3 };
const char* SceneLayoutName(SceneLayout layout);

enum class PlannedOverlapKind { kNone = 0, kSame = 1, kOblique = 2, kBrief = 3, kLong = 4 };
const char* PlannedOverlapName(PlannedOverlapKind kind);

/// What the generator intended for two neighbouring agents.
struct PlannedOverlap {
  int agent_a = 0, agent_b = 0;  ///< indices into the scenario's agents, a < b
  PlannedOverlapKind kind = PlannedOverlapKind::kNone;
  double view_angle_deg = 0.0;   ///< between the two agents' views of the shared target
  double seconds = 0.0;          ///< planned time on the shared arc (each agent, per lap)
  /// False when one of the two loops could not join the shared arc smoothly and flies
  /// without it (the target object stays; the ground truth tells what they saw).
  bool flown = true;
};

/// Largest team a generated scene holds (a 4 x 4 grid of cells); scenes of more than 8 agents
/// are never drawn by default (max_agents 8), so the seeds' scenes stay what they were.
inline constexpr int kMaxGeneratedAgents = 16;

struct SceneGeneratorOptions {
  int min_agents = 2, max_agents = 8;
  double min_duration_s = 25.0, max_duration_s = 40.0;  ///< flight time of every agent
  bool allow_fisheye = true;
  bool allow_motion_blur = true;
  std::string Validate() const;  ///< empty if usable
};

struct GeneratedScene {
  std::uint64_t seed = 0;
  std::string yaml;               ///< the scenario (name "gen-<seed>")
  SceneLayout layout = SceneLayout::kHall;
  std::string texture_profile;    ///< rich, mixed or weak
  std::string camera;             ///< euroc, vga, wide or fisheye
  double rate_hz = 0.0;
  bool motion_blur = false;
  int num_agents = 0;
  std::vector<PlannedOverlap> plan;  ///< every neighbouring pair, none included
  std::string Summary() const;       ///< one line: layout, agents, camera, profile
};

GeneratedScene GenerateScene(std::uint64_t seed, const SceneGeneratorOptions& options = {});

/// "gen:SEED" (decimal) -> the YAML of GenerateScene(SEED); "gen:SEED:MAX_AGENTS" -> the scene
/// drawn with that max_agents (bench_fusion --max-agents); nullopt for any other name.
std::optional<std::string> GeneratedScenarioYaml(const std::string& name);

}  // namespace ccm::sim
