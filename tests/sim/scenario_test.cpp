#include <cmath>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "tests/sim/sim_test_util.h"

namespace ccm::sim {
namespace {

using testing::SharedSim;

TEST(Scenario, BuiltinsParseAndValidate) {
  ASSERT_EQ(BuiltinScenarios().size(), 3u);
  for (const auto& [name, description] : BuiltinScenarios()) {
    std::string error;
    const auto s = LoadScenario(name, &error);
    ASSERT_TRUE(s) << error;
    EXPECT_EQ(s->name, name);
    EXPECT_EQ(s->Validate(), "");
  }
  const auto hall3 = LoadScenario("hall3", nullptr);
  ASSERT_EQ(hall3->agents.size(), 3u);
  EXPECT_EQ(hall3->camera.width_px, 752);
  EXPECT_NEAR(hall3->camera.fx, 458.654, 1e-9);
  EXPECT_EQ(hall3->agents[0].rate_hz, 20.0);
}

std::string ErrorFor(const std::string& yaml) {
  std::string error;
  EXPECT_FALSE(ParseScenarioYaml(yaml, "test.yaml", &error)) << yaml;
  return error;
}

TEST(Scenario, YamlErrorsSayWhereAndWhat) {
  const std::string agents = "agents:\n  - {name: a, duration_s: 5, waypoints: [[1, 1, 1], [3, 1, 1], [3, 3, 1]]}\n";
  const std::string room = "objects:\n  - {type: room, min: [0, 0, 0], max: [5, 5, 3]}\n";
  EXPECT_NE(ErrorFor("name: x\n" + room + agents + "colour: red\n").find("unknown key 'colour'"), std::string::npos);
  EXPECT_NE(ErrorFor("name: x\nobjects:\n  - {type: cone}\n" + agents).find("objects[0].type: unknown object type"),
            std::string::npos);
  EXPECT_NE(ErrorFor("name: x\n" + room + "agents:\n  - {name: a, duration_s: 5, waypoints: [[1, 1]]}\n")
                .find("agents[0].waypoints[0]: expected 3-4 numbers"),
            std::string::npos);
  EXPECT_NE(ErrorFor("name: x\nobjects:\n  - {type: room, min: [0, 0, 0], max: [5, 5, 3], walls: shiny}\n" + agents)
                .find("unknown texture style 'shiny'"),
            std::string::npos);
  EXPECT_NE(ErrorFor("name: x\n" + room).find("'agents' must be a list"), std::string::npos);
  EXPECT_NE(ErrorFor("name: x\n" + room + agents + "camera: {fx: -3}\n").find("camera"), std::string::npos);
  EXPECT_NE(ErrorFor("name: x\n" + room + agents + "render: {vignetting: abc}\n").find("render.vignetting: wrong type"),
            std::string::npos);
  EXPECT_NE(ErrorFor("name: [x\n").find("YAML syntax error"), std::string::npos);
  std::string error;
  EXPECT_FALSE(LoadScenario("/nonexistent/scene.yaml", &error));
  EXPECT_NE(error.find("neither a built-in scenario"), std::string::npos) << error;
}

// Surface cells (0.5 m squares) each agent sees, with the viewing directions, from a
// sparse grid of exact ray casts on every 10th frame.
struct Views {
  std::map<std::tuple<int, int, int>, std::vector<Eigen::Vector3d>> cells;
};

std::vector<Views> CollectViews(const Simulation& sim) {
  std::vector<Views> out(sim.num_agents());
  const CameraModel& cam = sim.renderer().camera();
  for (int a = 0; a < sim.num_agents(); ++a)
    for (std::int64_t i = 0; i < sim.NumFrames(a); i += 10) {
      const SE3 pose = sim.WorldFromCam(a, i);
      for (int gy = 1; gy < 8; ++gy)
        for (int gx = 1; gx < 10; ++gx) {
          const auto hit = sim.renderer().CastRay(pose, Eigen::Vector2d(gx * cam.width() / 10.0, gy * cam.height() / 8.0));
          if (!hit || hit->range_m > 12.0) continue;
          const auto key = std::make_tuple(hit->surface, static_cast<int>(std::floor(hit->surface_uv_m.x() / 0.5)),
                                           static_cast<int>(std::floor(hit->surface_uv_m.y() / 0.5)));
          out[a].cells[key].push_back((hit->point_w - pose.translation()).normalized());
        }
    }
  return out;
}

// Cells both agents saw from directions within 40 degrees: places where their maps can fuse.
int CommonViews(const Views& a, const Views& b) {
  int n = 0;
  for (const auto& [key, dirs_a] : a.cells) {
    const auto it = b.cells.find(key);
    if (it == b.cells.end()) continue;
    bool similar = false;
    for (const auto& da : dirs_a)
      for (const auto& db : it->second) similar |= da.dot(db) > std::cos(40 * M_PI / 180);
    n += similar ? 1 : 0;
  }
  return n;
}

TEST(Scenario, Hall3EveryPairOfAgentsSharesViews) {
  const auto views = CollectViews(*SharedSim("hall3"));
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b) {
      const int common = CommonViews(views[a], views[b]);
      EXPECT_GE(common, 25) << "agents " << a << ", " << b;
      RecordProperty("common_views_" + std::to_string(a) + std::to_string(b), common);
    }
}

TEST(Scenario, Disjoint2AgentsNeverSeeTheSameSurface) {
  const auto sim = SharedSim("disjoint2");
  const auto views = CollectViews(*sim);
  std::set<int> surfaces0;
  for (const auto& [key, d] : views[0].cells) surfaces0.insert(std::get<0>(key));
  int shared = 0;
  for (const auto& [key, d] : views[1].cells) shared += surfaces0.count(std::get<0>(key)) ? 1 : 0;
  EXPECT_EQ(shared, 0);
  EXPECT_GT(views[0].cells.size(), 50u);
  EXPECT_GT(views[1].cells.size(), 50u);
}

TEST(Scenario, RepeatedSceneReusesTextures) {
  const auto sim = SharedSim("repeated");
  const auto& surfaces = sim->world()->surfaces();
  std::map<int, int> uses;
  for (const Surface& s : surfaces) ++uses[s.texture];
  int max_uses = 0;
  for (const auto& [t, n] : uses) max_uses = std::max(max_uses, n);
  EXPECT_EQ(max_uses, 8);  // each face of the 8 identical crates
  EXPECT_LT(sim->world()->textures().size(), surfaces.size() / 2);
}

}  // namespace
}  // namespace ccm::sim
