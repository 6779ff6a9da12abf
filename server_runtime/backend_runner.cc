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
  for (const AgentId a : backend_->Status().agents) {
    threads_.emplace_back([this, a] {
      while (running_) backend_->RunHandlerOnce(a, kWait);
    });
  }
}

BackendRunner::~BackendRunner() { Stop(); }

void BackendRunner::StartHandler(AgentId agent) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!running_) return;
  threads_.emplace_back([this, agent] {
    while (running_) backend_->RunHandlerOnce(agent, kWait);
  });
}

void BackendRunner::Stop() {
  if (!running_.exchange(false)) return;
  backend_->Stop();
  std::vector<std::thread> threads;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    threads.swap(threads_);
  }
  for (auto& t : threads) t.join();
  backend_->SetNewAgentCallback({});
  backend_->Resume();
}

size_t BackendRunner::num_threads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return threads_.size();
}

}  // namespace ccm::server
