// Minimal child-process runner for multi-process transport tests: start several commands
// at once, capture each one's stdout+stderr in a file, wait for all (with a timeout).
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace ccm::testing {

struct ProcessResult {
  int exit_code = -1;
  std::string output;
};

inline std::vector<ProcessResult> RunConcurrently(const std::vector<std::vector<std::string>>& commands,
                                                  const std::string& log_prefix, std::chrono::seconds timeout) {
  std::vector<pid_t> pids;
  std::vector<std::string> logs;
  for (std::size_t i = 0; i < commands.size(); ++i) {
    logs.push_back(log_prefix + "." + std::to_string(i) + ".log");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, logs.back().c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    std::vector<char*> argv;
    for (const auto& arg : commands[i]) argv.push_back(const_cast<char*>(arg.c_str()));
    argv.push_back(nullptr);
    pid_t pid = -1;
    if (posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid = -1;
    posix_spawn_file_actions_destroy(&actions);
    pids.push_back(pid);
  }
  std::vector<ProcessResult> results(commands.size());
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (std::size_t i = 0; i < pids.size(); ++i) {
    if (pids[i] < 0) continue;
    int status = 0;
    // Poll waitpid so a hung child is killed at the deadline instead of hanging the test.
    while (waitpid(pids[i], &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        kill(pids[i], SIGKILL);
        waitpid(pids[i], &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    results[i].exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    std::ifstream in(logs[i]);
    std::stringstream text;
    text << in.rdbuf();
    results[i].output = text.str();
  }
  return results;
}

}  // namespace ccm::testing
