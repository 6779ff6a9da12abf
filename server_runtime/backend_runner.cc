#include "server_runtime/backend_runner.h"

namespace ccm::server {
namespace {
// Waits are bounded so that a missed Stop() could never hang a join; they are not polling:
// every stage wakes at once when work arrives.
constexpr std::chrono::milliseconds kWait(500);
}  // namespace

BackendRunner::BackendRunner(ServerBackend* backend) : backend_(backend) {
  backend_->SetNewAgentCallback([this](AgentId agent) { StartHandler(agent); });
  std::lock_guard<std::mutex> lock(mutex_);
  threads_.emplace_back([this] {
    while (running_) backend_->RunPlaceRecognitionOnce(kWait);
  });
  threads_.emplace_back([this] {
    while (running_) backend_->RunOptimizationOnce(kWait);
  });
  for (const AgentId a : backend_->Status().agents) StartHandlerLocked(a);
}

void BackendRunner::HandleAgent(AgentId agent) {
  // Ends when the agent's slot is released; the back-end asks for a new thread if it returns.
  while (running_ && backend_->RunHandlerOnce(agent, kWait) != ServerBackend::HandlerStep::kAgentReleased) {
  }
}

void BackendRunner::StartHandlerLocked(AgentId agent) {
  for (auto it = handlers_.begin(); it != handlers_.end();) {
    if (it->ended->load()) {
      it->thread.join();
      it = handlers_.erase(it);
    } else {
      ++it;
    }
  }
  auto ended = std::make_shared<std::atomic<bool>>(false);
  handlers_.push_back({std::thread([this, agent, ended] {
                         HandleAgent(agent);
                         ended->store(true);
                       }),
                       ended});
}

BackendRunner::~BackendRunner() { Stop(); }

void BackendRunner::StartHandler(AgentId agent) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (running_) StartHandlerLocked(agent);
}

void BackendRunner::Stop() {
  if (!running_.exchange(false)) return;
  backend_->Stop();
  std::vector<std::thread> threads;
  std::list<Handler> handlers;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    threads.swap(threads_);
    handlers.swap(handlers_);
  }
  for (auto& t : threads) t.join();
  for (auto& h : handlers) h.thread.join();
  backend_->SetNewAgentCallback({});
  backend_->Resume();
}

size_t BackendRunner::num_threads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  size_t running_handlers = 0;
  for (const Handler& h : handlers_) running_handlers += h.ended->load() ? 0 : 1;
  return threads_.size() + running_handlers;
}

}  // namespace ccm::server
