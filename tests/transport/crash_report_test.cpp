// The runtimes' crash report (rt::SetUpGlog, called first in ccm_server, ccm_agent and
// ccm_fleet): a process that dies on a signal names the signal and prints its stack on stderr.
// A live test once saw ccm_server die ~22 s into a fleet run with nothing in its output but
// the exit status; these tests make sure the next such death says where it happened.
#include <gtest/gtest.h>

#include <csignal>
#include <stdexcept>
#include <thread>

#include "runtime_common/runtime_cli.h"

namespace ccm {
namespace {

// Not inlined, so the trace has a frame of this file's own to name.
[[gnu::noinline]] void CrashInMapCode() { std::raise(SIGSEGV); }

TEST(CrashReportDeathTest, ASegfaultNamesTheSignalAndPrintsTheStack) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(
      {
        rt::SetUpGlog("crash_report_test");
        CrashInMapCode();
      },
      "SIGSEGV.*received by PID[^@]*@ +0x[0-9a-f]+");
}

TEST(CrashReportDeathTest, AnUncaughtExceptionPrintsItsMessageAndTheStack) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(
      {
        rt::SetUpGlog("crash_report_test");
        // As in a worker thread of the server: nothing above it catches.
        std::thread([] { throw std::runtime_error("map point 42 has no observation"); }).join();
      },
      "map point 42 has no observation.*SIGABRT.*@ +0x[0-9a-f]+");
}

}  // namespace
}  // namespace ccm
