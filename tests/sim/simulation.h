// A ready-to-render scenario: world (textures drawn once), renderer, and one trajectory
// per agent. Frame i of agent a is a pure function of (scenario, a, i): any frame can be
// rendered in any order, from any thread, and is byte-identical every time.
// Use: Simulation::Create(scenario) then RenderFrame / WorldFromCam, or wrap an agent in
// a SimFrameSource, or write EuRoC folders with WriteEurocAgent.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "slam_core/geometry/se3.h"
#include "tests/sim/renderer.h"
#include "tests/sim/scenario.h"
#include "tests/sim/trajectory.h"
#include "tests/sim/world.h"

namespace ccm::sim {

class Simulation {
 public:
  /// nullptr + *error if the scenario is invalid. `world` may be passed to reuse the
  /// textures of an identical world spec + seed (e.g. the same scene with another camera).
  static std::unique_ptr<Simulation> Create(const Scenario& scenario, std::string* error,
                                            std::shared_ptr<const World> world = nullptr);

  const Scenario& scenario() const { return scenario_; }
  int num_agents() const { return static_cast<int>(trajectories_.size()); }
  const std::string& agent_name(int agent) const { return scenario_.agents.at(agent).name; }
  /// Frames of an agent: one every 1/rate_hz seconds while t <= duration_s.
  std::int64_t NumFrames(int agent) const;
  double TimeS(int agent, std::int64_t index) const;
  std::int64_t StampNs(int agent, std::int64_t index) const;
  SE3 WorldFromCam(int agent, std::int64_t index) const;
  /// Exposure gain of the agent's camera at time t (smooth drift around 1).
  float Gain(int agent, double t_s) const;
  /// The 8-bit image of frame `index` (motion blur, gain and noise as the scenario says).
  cv::Mat RenderFrame(int agent, std::int64_t index) const;

  const Renderer& renderer() const { return *renderer_; }
  const Trajectory& trajectory(int agent) const { return *trajectories_.at(agent); }
  std::shared_ptr<const World> world() const { return world_; }

 private:
  Simulation() = default;

  Scenario scenario_;
  std::shared_ptr<const World> world_;
  std::unique_ptr<Renderer> renderer_;
  std::vector<std::unique_ptr<Trajectory>> trajectories_;
};

}  // namespace ccm::sim
