// Wall-clock time for message stamps (ns since the Unix epoch): what agents and server put
// in stamp_ns, comparable across machines with synchronized clocks.
#pragma once

#include <chrono>
#include <cstdint>

namespace ccm::rt {

inline int64_t WallClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace ccm::rt
