// A simulation scenario: the world, the camera, render settings and the agents' flights.
// Scenarios come from YAML (a file, or one of the built-in texts: hall3, disjoint2,
// repeated); the format is documented in docs/simulator.md. Parsing lives here, not in
// the renderer, so the rendering code only sees validated structs.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/geometry/camera.h"
#include "tests/sim/renderer.h"
#include "tests/sim/trajectory.h"
#include "tests/sim/world.h"

namespace ccm::sim {

struct AgentSpec {
  std::string name;            ///< folder name of the agent's EuRoC output
  double rate_hz = 20.0;       ///< camera frame rate
  TrajectorySpec trajectory;
};

struct Scenario {
  std::string name;
  std::string description;
  std::uint64_t seed = 1;                        ///< textures, sensor noise
  std::int64_t start_stamp_ns = 1'600'000'000'000'000'000;  ///< stamp of frame 0 (all agents)
  WorldSpec world;
  CameraIntrinsics camera;
  RenderOptions render;
  double exposure_variation = 0.1;               ///< relative amplitude of the gain drift
  double exposure_period_s = 23.0;               ///< period of the gain drift
  std::vector<AgentSpec> agents;
  std::string Validate() const;                  ///< empty if usable, else the first problem
};

/// EuRoC MH cam0-like pinhole radial-tangential camera (752x480, fx 458.654).
CameraIntrinsics EurocCamera();
/// Equidistant fisheye with the same resolution (about 170 degrees across).
CameraIntrinsics FisheyeCamera();

/// Names and one-line descriptions of the built-in scenarios.
std::vector<std::pair<std::string, std::string>> BuiltinScenarios();
/// YAML text of a built-in scenario, nullopt if unknown.
std::optional<std::string> BuiltinScenarioYaml(const std::string& name);

/// Parses scenario YAML text; `origin` names the source in error messages.
std::optional<Scenario> ParseScenarioYaml(const std::string& text, const std::string& origin, std::string* error);
/// A built-in name or a path to a YAML file.
std::optional<Scenario> LoadScenario(const std::string& name_or_path, std::string* error);

}  // namespace ccm::sim
