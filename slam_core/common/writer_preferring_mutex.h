// A reader/writer mutex that lets a waiting writer in before new readers. glibc's
// std::shared_mutex prefers readers, so on the server, where several agent handlers hold the
// map's structure lock shared in overlapping turns, a loop closure or fusion waiting for the
// exclusive lock could starve. Meets the SharedMutex requirements (std::shared_lock,
// std::unique_lock work). Not recursive.
#pragma once

#include <condition_variable>
#include <mutex>

namespace ccm {

class WriterPreferringMutex {
 public:
  void lock() {
    std::unique_lock<std::mutex> l(m_);
    ++writers_waiting_;
    cv_.wait(l, [this] { return !writer_active_ && readers_ == 0; });
    --writers_waiting_;
    writer_active_ = true;
  }
  bool try_lock() {
    std::lock_guard<std::mutex> l(m_);
    if (writer_active_ || readers_ > 0) return false;
    writer_active_ = true;
    return true;
  }
  void unlock() {
    {
      std::lock_guard<std::mutex> l(m_);
      writer_active_ = false;
    }
    cv_.notify_all();
  }
  void lock_shared() {
    std::unique_lock<std::mutex> l(m_);
    cv_.wait(l, [this] { return !writer_active_ && writers_waiting_ == 0; });
    ++readers_;
  }
  bool try_lock_shared() {
    std::lock_guard<std::mutex> l(m_);
    if (writer_active_ || writers_waiting_ > 0) return false;
    ++readers_;
    return true;
  }
  void unlock_shared() {
    bool last;
    {
      std::lock_guard<std::mutex> l(m_);
      last = --readers_ == 0;
    }
    if (last) cv_.notify_all();
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  int readers_ = 0;
  int writers_waiting_ = 0;
  bool writer_active_ = false;
};

}  // namespace ccm
