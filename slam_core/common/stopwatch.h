#pragma once

#include <chrono>

namespace ccm {

/// Seconds of steady-clock time since `t0` (for the timings the stages report).
inline double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace ccm
