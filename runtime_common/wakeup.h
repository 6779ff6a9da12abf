// A thread that serves several queues waits on one Wakeup instead of sleep-polling them:
// every producer Signal()s after it pushed, the consumer WaitFor()s until a signal or its
// next deadline. A signal given while the consumer was busy is not lost (it is counted), so
// the consumer's next wait returns at once.
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>

namespace ccm::rt {

class Wakeup {
 public:
  void Signal() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      signalled_ = true;
    }
    cv_.notify_one();
  }
  /// Returns true if signalled (now or since the last wait), false on timeout.
  template <typename Rep, typename Period>
  bool WaitFor(std::chrono::duration<Rep, Period> timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool signalled = cv_.wait_for(lock, timeout, [&] { return signalled_; });
    signalled_ = false;
    return signalled;
  }

 private:
  std::mutex mutex_;  // leaf
  std::condition_variable cv_;
  bool signalled_ = false;
};

}  // namespace ccm::rt
