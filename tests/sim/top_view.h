// A top view of a scenario for people: walls and object outlines in grey, each agent's
// flight path in its own colour with its start marked, so a generated scene can be checked
// at a glance (`ccm_sim --scenario gen:7 --top-view scene.png`).
#pragma once

#include <string>

#include "tests/sim/simulation.h"

namespace ccm::sim {

/// Writes a PNG about `width_px` wide; false + *error if it cannot be written.
bool WriteTopView(const Simulation& sim, const std::string& path, int width_px, std::string* error);

}  // namespace ccm::sim
