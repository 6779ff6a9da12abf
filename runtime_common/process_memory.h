// Memory of the running process, for the agent's footprint and the server's summary
// (docs/deployment.md "Footprint"). Linux/POSIX; one syscall.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <fstream>

namespace ccm::rt {

/// Peak resident set size of the process [MB].
inline double PeakRssMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // ru_maxrss is in kB on Linux
}

/// Resident set size of the process now [MB] (/proc/self/statm; 0 where it is missing).
inline double CurrentRssMb() {
  std::ifstream statm("/proc/self/statm");
  long pages_total = 0, pages_resident = 0;
  if (!(statm >> pages_total >> pages_resident)) return 0.0;
  return static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

}  // namespace ccm::rt
