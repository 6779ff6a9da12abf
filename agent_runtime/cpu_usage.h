// CPU time and memory of the agent process, for the footprint in the agent's summary
// (docs/deployment.md "Footprint"): per-thread CPU from CLOCK_THREAD_CPUTIME_ID (the calling
// thread only), process CPU from getrusage (peak RSS: runtime_common/process_memory.h).
// Linux/POSIX; cheap (one syscall).
#pragma once

#include <sys/resource.h>

#include <ctime>

namespace ccm::agent {

/// CPU seconds the calling thread has used so far.
inline double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// CPU seconds (user + system) of the whole process, all threads, so far.
inline double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace ccm::agent
