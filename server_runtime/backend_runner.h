// Runs the server back-end's stages on threads: one handler thread per agent (started when
// the agent first submits, or at start for agents that submitted before, e.g. to a runner
// stopped earlier; a loaded map's agents start theirs when they submit; it ends when the
// agent's slot is released and starts again if the agent returns), one place-recognition
// thread, one optimization thread. It owns and joins them all (ended handler threads when
// the next one starts); the back-end stays a thread-agnostic library. Used by ccm_server
// and by ccm_replay's threaded mode.
#pragma once

#include <atomic>
#include <list>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "slam_core/server/server_backend.h"

namespace ccm::server {

class BackendRunner {
 public:
  /// Starts the threads at once; install before the first Submit (it sets the back-end's
  /// new-agent callback).
  explicit BackendRunner(ServerBackend* backend);
  ~BackendRunner();
  BackendRunner(const BackendRunner&) = delete;
  BackendRunner& operator=(const BackendRunner&) = delete;

  /// Stops the back-end's stages and joins every thread. Idempotent.
  void Stop();
  /// Threads running: place recognition, optimization and every agent's handler.
  size_t num_threads() const;

 private:
  void StartHandler(AgentId agent);
  void HandleAgent(AgentId agent);
  /// Joins ended handler threads, then starts `agent`'s (mutex_ held).
  void StartHandlerLocked(AgentId agent);

  struct Handler {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> ended;
  };

  ServerBackend* backend_;
  std::atomic<bool> running_{true};
  mutable std::mutex mutex_;  // guards threads_ and handlers_; leaf
  std::vector<std::thread> threads_;  ///< place recognition, optimization
  std::list<Handler> handlers_;
};

}  // namespace ccm::server
