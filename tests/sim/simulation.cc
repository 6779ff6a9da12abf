#include "tests/sim/simulation.h"

#include <cmath>

#include "tests/sim/sim_random.h"

namespace ccm::sim {

std::unique_ptr<Simulation> Simulation::Create(const Scenario& scenario, std::string* error,
                                               std::shared_ptr<const World> world) {
  auto fail = [&](const std::string& e) {
    if (error) *error = "scenario '" + scenario.name + "': " + e;
    return nullptr;
  };
  if (std::string e = scenario.Validate(); !e.empty()) return fail(e);
  std::unique_ptr<Simulation> sim(new Simulation());
  sim->scenario_ = scenario;
  for (const AgentSpec& a : scenario.agents) {
    std::string e;
    auto traj = Trajectory::Create(a.trajectory, &e);
    if (!traj) return fail("agent '" + a.name + "': " + e);
    sim->trajectories_.push_back(std::move(traj));
  }
  sim->world_ = world ? std::move(world) : std::make_shared<const World>(scenario.world, scenario.seed);
  std::string e;
  sim->renderer_ = Renderer::Create(sim->world_, scenario.camera, scenario.render, &e);
  if (!sim->renderer_) return fail(e);
  return sim;
}

std::int64_t Simulation::NumFrames(int agent) const {
  const AgentSpec& a = scenario_.agents.at(agent);
  return static_cast<std::int64_t>(std::floor(a.trajectory.duration_s * a.rate_hz + 1e-9)) + 1;
}

double Simulation::TimeS(int agent, std::int64_t index) const {
  return static_cast<double>(index) / scenario_.agents.at(agent).rate_hz;
}

std::int64_t Simulation::StampNs(int agent, std::int64_t index) const {
  return scenario_.start_stamp_ns + std::llround(static_cast<double>(index) * 1e9 / scenario_.agents.at(agent).rate_hz);
}

SE3 Simulation::WorldFromCam(int agent, std::int64_t index) const {
  return trajectories_.at(agent)->WorldFromCam(TimeS(agent, index));
}

float Simulation::Gain(int agent, double t) const {
  const double phase = 2.0 * M_PI * static_cast<double>(HashCombine(scenario_.seed, agent) % 1000) / 1000.0;
  return static_cast<float>(1.0 + scenario_.exposure_variation *
                                      std::sin(2.0 * M_PI * t / scenario_.exposure_period_s + phase));
}

cv::Mat Simulation::RenderFrame(int agent, std::int64_t index) const {
  const double t = TimeS(agent, index);
  const Trajectory& traj = *trajectories_.at(agent);
  const int n = scenario_.render.motion_blur_samples;
  std::vector<SE3> poses;
  if (n <= 1) {
    poses.push_back(traj.WorldFromCam(t));
  } else {
    // Shutter centred on the frame time, so the ground-truth pose is the mean pose.
    for (int k = 0; k < n; ++k)
      poses.push_back(traj.WorldFromCam(t + scenario_.render.exposure_time_s * (double(k) / (n - 1) - 0.5)));
  }
  const std::uint64_t key = HashCombine(HashCombine(scenario_.seed, static_cast<std::uint64_t>(agent) + 1),
                                        static_cast<std::uint64_t>(index));
  return renderer_->Render(poses, Gain(agent, t), key);
}

}  // namespace ccm::sim
