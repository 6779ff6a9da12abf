// How many inputs a fuzz test runs: a few thousand in the normal test run (CI stays fast),
// CCM_FUZZ_INPUTS in the environment for the sanitizer job (deploy/run-sanitizer-tests.sh
// sets 100,000).
#pragma once

#include <cstdlib>
#include <string>

namespace ccm::testing {

inline int FuzzInputs(int normal_run) {
  const char* env = std::getenv("CCM_FUZZ_INPUTS");
  if (!env || !*env) return normal_run;
  const long n = std::strtol(env, nullptr, 10);
  return n > 0 ? static_cast<int>(n) : normal_run;
}

}  // namespace ccm::testing
