// Peak memory of the running process, for the agent's footprint and the server's summary
// (docs/deployment.md "Footprint"). Linux/POSIX; one syscall.
#pragma once

#include <sys/resource.h>

namespace ccm::rt {

/// Peak resident set size of the process [MB].
inline double PeakRssMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // ru_maxrss is in kB on Linux
}

}  // namespace ccm::rt
