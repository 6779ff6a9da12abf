// Built-in scenarios, kept as YAML text so that they exercise the same parser as user
// files and can be printed (`ccm_sim --dump hall3`) as a starting point for new ones.
#include "tests/sim/scenario.h"

namespace ccm::sim {

namespace {

// Indoor hall 24 x 16 x 6 m: four pillars, shelves along two walls, crates. Three loops
// that each circle a different part of the hall and all pass around the central island,
// so every agent revisits its own path and every pair of agents sees common structure.
const char* const kHall3 = R"(name: hall3
description: indoor hall 24x16x6 m, 3 agents flying loops (60-80 s at 20 Hz), pairwise overlap
seed: 3
texel_m: 0.008
objects:
  - {type: room, name: hall, min: [0, 0, 0], max: [24, 16, 6], floor: mixed, ceiling: weak, walls: rich, grey: 125}
  - {type: pillar, name: pillar_sw, center: [8, 5.5], size: [0.6, 0.6, 6], style: rich, grey: 150}
  - {type: pillar, name: pillar_se, center: [16, 5.5], size: [0.6, 0.6, 6], style: rich, grey: 140}
  - {type: pillar, name: pillar_nw, center: [8, 10.5], size: [0.6, 0.6, 6], style: rich, grey: 145}
  - {type: pillar, name: pillar_ne, center: [16, 10.5], size: [0.6, 0.6, 6], style: rich, grey: 135}
  - {type: box, name: island, center: [12, 8], size: [2.0, 1.2, 0.9], yaw_deg: 10, style: rich, grey: 120}
  - {type: box, name: shelf_n1, center: [3.5, 15.3], size: [4.0, 0.8, 2.2], style: rich, grey: 110}
  - {type: box, name: shelf_n2, center: [11, 15.3], size: [4.0, 0.8, 2.2], style: rich, grey: 130}
  - {type: box, name: shelf_n3, center: [19, 15.3], size: [4.0, 0.8, 2.2], style: rich, grey: 115}
  - {type: box, name: shelf_s1, center: [9.5, 0.55], size: [3.0, 0.7, 1.8], style: rich, grey: 125}
  - {type: box, name: crate_1, center: [3.5, 1.2], size: [1.4, 0.9, 1.0], yaw_deg: 5, style: rich, grey: 140}
  - {type: box, name: crate_2, center: [1.0, 14.5], size: [1.2, 1.2, 1.5], style: rich, grey: 100}
  - {type: box, name: crate_3, center: [5.5, 7.5], size: [1.0, 1.0, 1.3], yaw_deg: 25, style: rich, grey: 150}
  - {type: box, name: crate_4, center: [19, 7.5], size: [1.5, 1.5, 1.2], yaw_deg: -15, style: rich, grey: 120}
  - {type: box, name: crate_5, center: [23.0, 1.0], size: [1.4, 1.4, 2.0], style: rich, grey: 135}
  - {type: box, name: crate_6, center: [22.8, 14.8], size: [1.5, 1.5, 1.0], style: rich, grey: 105}
  - {type: box, name: crate_7, center: [16.5, 0.8], size: [1.0, 1.0, 0.8], yaw_deg: 30, style: rich, grey: 145}
  - {type: box, name: crate_8, center: [0.6, 9.0], size: [0.8, 1.6, 1.1], style: rich, grey: 115}
  - {type: box, name: crate_9, center: [23.4, 11.0], size: [0.8, 2.0, 1.5], style: rich, grey: 125}
  - {type: box, name: crate_10, center: [5.5, 7.5], size: [0.6, 0.6, 0.5], base_z: 1.3, yaw_deg: 60, style: rich, grey: 90}
agents:
  - name: agent0
    duration_s: 80
    speed_mps: [0.4, 1.2]
    pitch_deg: -14
    waypoints: [[2.5, 4, 1.5, 20], [6, 2.5, 1.8, 30], [11, 3.5, 2.2, 40], [13, 6.5, 1.6, 45],
                [10.5, 9.5, 1.6, 30], [7, 13, 2.0, 20], [2.5, 11, 2.4, 35], [2, 7.5, 1.8, 30]]
  - name: agent1
    duration_s: 70
    speed_mps: [0.35, 1.1]
    speed_period_s: 13
    pitch_deg: -10
    waypoints: [[21.5, 4, 1.6, 30], [18, 2.3, 2.0, 40], [14.5, 5.5, 1.5, 35], [13.2, 9.5, 1.8, 25],
                [16.5, 13, 2.3, 30], [20.5, 12.2, 1.8, 40], [22.6, 8, 1.4, 30]]
  - name: agent2
    duration_s: 65
    speed_mps: [0.45, 1.3]
    speed_period_s: 19
    pitch_deg: -18
    waypoints: [[12, 2, 1.7, -30], [15, 3.5, 1.4, -40], [14.2, 8, 2.2, -30], [15, 12.8, 1.8, -35],
                [12, 13.3, 2.0, -40], [9.2, 12.5, 1.6, -30], [9.8, 8, 2.4, -35], [9, 3.5, 1.5, -40]]
)";

// Two closed rooms 100 m apart with their own textures: the agents never see a common place.
const char* const kDisjoint2 = R"(name: disjoint2
description: two separate rooms 100 m apart, one agent each (60 s at 20 Hz), never a common view
seed: 22
texel_m: 0.008
objects:
  - {type: room, name: room_a, min: [0, 0, 0], max: [12, 10, 4], floor: mixed, ceiling: weak, walls: rich, grey: 120}
  - {type: pillar, name: a_pillar, center: [6, 5], size: [0.5, 0.5, 4], style: rich, grey: 140}
  - {type: box, name: a_crate_1, center: [2, 2], size: [1.2, 1.0, 1.0], style: rich, grey: 110}
  - {type: box, name: a_crate_2, center: [10, 8], size: [1.0, 1.4, 1.4], yaw_deg: 20, style: rich, grey: 150}
  - {type: box, name: a_shelf, center: [6, 9.4], size: [4.0, 0.8, 2.0], style: rich, grey: 125}
  - {type: room, name: room_b, min: [100, 0, 0], max: [112, 10, 4], floor: mixed, ceiling: weak, walls: rich, grey: 135}
  - {type: pillar, name: b_pillar, center: [106, 5], size: [0.5, 0.5, 4], style: rich, grey: 120}
  - {type: box, name: b_crate_1, center: [102, 8], size: [1.0, 1.2, 1.2], yaw_deg: -10, style: rich, grey: 145}
  - {type: box, name: b_crate_2, center: [110, 2], size: [1.4, 1.0, 0.9], style: rich, grey: 100}
  - {type: box, name: b_shelf, center: [106, 0.6], size: [4.0, 0.8, 2.0], style: rich, grey: 130}
agents:
  - name: agent0
    duration_s: 60
    speed_mps: [0.4, 1.1]
    waypoints: [[2.5, 5, 1.5, 30], [4, 2.5, 1.8, 35], [8.5, 2.5, 1.4, 30], [9.5, 5.5, 2.0, 35], [7.5, 7.5, 1.6, 30], [3.5, 7.5, 1.9, 35]]
  - name: agent1
    duration_s: 60
    speed_mps: [0.4, 1.1]
    waypoints: [[109.5, 5, 1.5, 30], [108, 7.5, 1.8, 35], [104, 6.5, 1.4, 30], [102.5, 4, 2.0, 35], [104, 2.5, 1.6, 30], [107.5, 3, 1.9, 35]]
)";

// A hall with rows of identical crates and pillars (shared textures): many places look
// alike, which is what a place-recognition false-positive test needs.
const char* const kRepeated = R"(name: repeated
description: hall with rows of identical crates and pillars (shared textures), 2 agents (60 s)
seed: 5
texel_m: 0.008
objects:
  - {type: room, name: hall, min: [0, 0, 0], max: [26, 12, 5], floor: mixed, ceiling: weak, walls: mixed, grey: 125}
  - {type: pillar, name: pillar_1, center: [5, 6], size: [0.5, 0.5, 5], style: rich, grey: 140, share: pillar}
  - {type: pillar, name: pillar_2, center: [10, 6], size: [0.5, 0.5, 5], style: rich, grey: 140, share: pillar}
  - {type: pillar, name: pillar_3, center: [15, 6], size: [0.5, 0.5, 5], style: rich, grey: 140, share: pillar}
  - {type: pillar, name: pillar_4, center: [20, 6], size: [0.5, 0.5, 5], style: rich, grey: 140, share: pillar}
  - {type: box, name: crate_s1, center: [5, 1.2], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_s2, center: [10, 1.2], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_s3, center: [15, 1.2], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_s4, center: [20, 1.2], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_n1, center: [5, 10.8], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_n2, center: [10, 10.8], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_n3, center: [15, 10.8], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
  - {type: box, name: crate_n4, center: [20, 10.8], size: [1.6, 1.0, 1.4], style: rich, grey: 120, share: crate}
agents:
  - name: agent0
    duration_s: 60
    speed_mps: [0.6, 1.4]
    waypoints: [[3.5, 3.5, 1.6, 50], [12, 3.4, 1.8, 55], [20.5, 3.5, 1.6, 50], [22.8, 4.6, 1.7, 50],
                [23.4, 6, 1.8, 50], [22.8, 7.4, 1.7, 50], [20.5, 8.5, 1.8, 50], [12, 8.6, 1.6, 55],
                [3.5, 8.5, 1.8, 50], [1.6, 7.3, 1.7, 50], [1.2, 6, 1.6, 50], [1.6, 4.7, 1.7, 50]]
  - name: agent1
    duration_s: 60
    speed_mps: [0.6, 1.4]
    waypoints: [[20.5, 8.5, 1.7, -50], [12, 8.4, 1.5, -55], [3.5, 8.5, 1.7, -50], [1.6, 7.3, 1.6, -50],
                [1.2, 6, 1.5, -50], [1.6, 4.7, 1.6, -50], [3.5, 3.5, 1.7, -50], [12, 3.6, 1.5, -55],
                [20.5, 3.5, 1.7, -50], [22.8, 4.6, 1.6, -50], [23.4, 6, 1.5, -50], [22.8, 7.4, 1.6, -50]]
)";

}  // namespace

std::vector<std::pair<std::string, std::string>> BuiltinScenarios() {
  return {{"hall3", "indoor hall, 3 agents flying loops, every pair overlaps (default)"},
          {"disjoint2", "two rooms 100 m apart, 2 agents that never see the same place"},
          {"repeated", "hall with rows of identical crates and pillars, 2 agents (place-recognition traps)"}};
}

std::optional<std::string> BuiltinScenarioYaml(const std::string& name) {
  if (name == "hall3") return std::string(kHall3);
  if (name == "disjoint2") return std::string(kDisjoint2);
  if (name == "repeated") return std::string(kRepeated);
  return std::nullopt;
}

}  // namespace ccm::sim
