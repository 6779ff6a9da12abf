// Helpers shared by the sim_test sources: built-in simulations are built once per process.
#pragma once

#include <map>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "tests/sim/simulation.h"

namespace ccm::sim::testing {

inline Scenario BuiltinOrDie(const std::string& name) {
  std::string error;
  auto s = LoadScenario(name, &error);
  if (!s) ADD_FAILURE() << error;
  return s ? *s : Scenario();
}

inline std::shared_ptr<const Simulation> SharedSim(const std::string& name) {
  static std::map<std::string, std::shared_ptr<const Simulation>> cache;
  auto& slot = cache[name];
  if (!slot) {
    std::string error;
    slot = Simulation::Create(BuiltinOrDie(name), &error);
    if (!slot) ADD_FAILURE() << error;
  }
  return slot;
}

}  // namespace ccm::sim::testing
