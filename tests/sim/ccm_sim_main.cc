// ccm_sim: renders a scenario's agents into EuRoC ASL folders.
//   ccm_sim --scenario hall3 --out DIR [--agents 0,1] [--seconds S] [--rate HZ] [--seed N] [--fisheye]
//   ccm_sim --list | --dump NAME
#include <chrono>
#include <cstdio>
#include <optional>
#include <sstream>

#include <CLI/CLI.hpp>

#include "tests/sim/euroc_writer.h"
#include "tests/sim/scenario.h"
#include "tests/sim/scene_generator.h"
#include "tests/sim/simulation.h"
#include "tests/sim/top_view.h"

namespace {

bool ParseAgentList(const std::string& text, int n_agents, std::vector<int>* out, std::string* error) {
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      const int a = std::stoi(item, &used);
      if (used != item.size() || a < 0 || a >= n_agents) throw std::out_of_range(item);
      out->push_back(a);
    } catch (const std::exception&) {
      *error = "--agents: '" + item + "' is not an agent index in [0, " + std::to_string(n_agents - 1) + "]";
      return false;
    }
  }
  if (out->empty()) *error = "--agents: empty list";
  return !out->empty();
}

struct CliOptions {
  std::string scenario = "hall3", out_dir, agents, dump, top_view;
  double seconds = -1.0, rate = -1.0;
  long long seed = -1;
  bool fisheye = false, list = false;
};

// Loads the scenario and applies the command-line overrides; nullopt + *error on failure.
std::optional<ccm::sim::Scenario> PrepareScenario(const CliOptions& o, std::string* error) {
  if (o.seconds == 0.0 || o.rate == 0.0) {
    *error = "--seconds and --rate must be > 0";
    return std::nullopt;
  }
  auto scenario = ccm::sim::LoadScenario(o.scenario, error);
  if (!scenario) return std::nullopt;
  for (auto& a : scenario->agents) {
    if (o.seconds > 0) a.trajectory.duration_s = o.seconds;
    if (o.rate > 0) a.rate_hz = o.rate;
  }
  if (o.seed >= 0) scenario->seed = static_cast<std::uint64_t>(o.seed);
  if (o.fisheye) scenario->camera = ccm::sim::FisheyeCamera();
  return scenario;
}

int WriteAgents(const ccm::sim::Simulation& sim, const std::vector<int>& agents, const std::string& out_dir) {
  for (int a : agents) {
    const auto start = std::chrono::steady_clock::now();
    const auto progress = [&](std::int64_t done, std::int64_t total) {
      if (done % 100 != 0 && done != total) return;
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("\r%s: %lld/%lld frames (%.1f fps)", sim.agent_name(a).c_str(), static_cast<long long>(done),
                  static_cast<long long>(total), done / std::max(s, 1e-9));
      std::fflush(stdout);
    };
    const std::string error = ccm::sim::WriteEurocAgent(sim, a, out_dir, -1, progress);
    std::printf("\n");
    if (!error.empty()) {
      std::fprintf(stderr, "error: agent %s: %s\n", sim.agent_name(a).c_str(), error.c_str());
      return 1;
    }
  }
  std::printf("wrote %zu agent folder(s) under %s\n", agents.size(), out_dir.c_str());
  return 0;
}

int Fail(const std::string& error) {
  std::fprintf(stderr, "error: %s\n", error.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ccm_sim: photometric multi-agent scene simulator writing EuRoC ASL folders"};
  CliOptions o;
  app.add_option("--scenario", o.scenario, "built-in scenario name or YAML file")->capture_default_str();
  app.add_option("--out", o.out_dir, "output folder (one sub-folder per agent)");
  app.add_option("--agents", o.agents, "comma-separated agent indices, default all");
  app.add_option("--seconds", o.seconds, "flight duration per agent [s], overrides the scenario");
  app.add_option("--rate", o.rate, "camera rate [Hz], overrides the scenario");
  app.add_option("--seed", o.seed, "random seed (textures, noise), overrides the scenario");
  app.add_flag("--fisheye", o.fisheye, "use the equidistant fisheye camera");
  app.add_option("--top-view", o.top_view, "write a PNG top view of the scenario (walls, objects, flights)");
  app.add_flag("--list", o.list, "list the built-in scenarios and exit");
  app.add_option("--dump", o.dump, "print the YAML of a built-in (or generated: gen:SEED) scenario and exit");
  CLI11_PARSE(app, argc, argv);

  if (o.list) {
    for (const auto& [name, text] : ccm::sim::BuiltinScenarios()) std::printf("%-10s %s\n", name.c_str(), text.c_str());
    std::printf("%-10s %s\n", "gen:SEED[:N]", "a generated scene (room, hall, yard or corridor, 2-8 agents, or 2-N; docs/simulator.md)");
    return 0;
  }
  if (!o.dump.empty()) {
    auto text = ccm::sim::BuiltinScenarioYaml(o.dump);
    if (!text) text = ccm::sim::GeneratedScenarioYaml(o.dump);
    if (!text) return Fail("no built-in scenario '" + o.dump + "' (see --list; gen:SEED for a generated one)");
    std::fputs(text->c_str(), stdout);
    return 0;
  }
  if (o.out_dir.empty() && o.top_view.empty()) return Fail("--out DIR is required (or use --list, --top-view)");
  std::string error;
  const auto scenario = PrepareScenario(o, &error);
  if (!scenario) return Fail(error);
  if (o.out_dir.empty()) {
    const auto sim = ccm::sim::Simulation::Create(*scenario, &error);
    if (!sim) return Fail(error);
    if (!ccm::sim::WriteTopView(*sim, o.top_view, 1000, &error)) return Fail(error);
    std::printf("wrote %s\n", o.top_view.c_str());
    return 0;
  }
  std::vector<int> agents;
  if (o.agents.empty()) {
    for (size_t i = 0; i < scenario->agents.size(); ++i) agents.push_back(static_cast<int>(i));
  } else if (!ParseAgentList(o.agents, static_cast<int>(scenario->agents.size()), &agents, &error)) {
    return Fail(error);
  }
  std::printf("building world '%s' (%zu objects)...\n", scenario->name.c_str(), scenario->world.objects.size());
  std::fflush(stdout);
  const auto sim = ccm::sim::Simulation::Create(*scenario, &error);
  if (!sim) return Fail(error);
  return WriteAgents(*sim, agents, o.out_dir);
}
