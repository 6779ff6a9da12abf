// Per-topic, per-direction traffic counters shared by the writers/readers of one DDS
// session. Lock-free counters: written from application and listener threads, read by
// whoever reports (status messages, benchmarks, logs).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

namespace ccm::rt {

struct TopicCounters {
  std::atomic<std::uint64_t> samples{0};
  std::atomic<std::uint64_t> payload_bytes{0};     // serialized CDR size incl. encapsulation
  std::atomic<std::uint64_t> write_failures{0};    // DataWriter::write() returned false
  std::atomic<std::uint64_t> samples_lost{0};      // reported by the reader (BEST_EFFORT gaps)
  std::atomic<std::uint64_t> queue_dropped{0};     // evicted from the application queue
};

struct TopicCountersSnapshot {
  std::string topic;
  std::string direction;  // "out" or "in"
  std::uint64_t samples = 0;
  std::uint64_t payload_bytes = 0;
  std::uint64_t write_failures = 0;
  std::uint64_t samples_lost = 0;
  std::uint64_t queue_dropped = 0;
};

inline TopicCountersSnapshot Snapshot(const std::string& topic, const std::string& direction,
                                      const TopicCounters& c) {
  TopicCountersSnapshot s;
  s.topic = topic;
  s.direction = direction;
  s.samples = c.samples.load();
  s.payload_bytes = c.payload_bytes.load();
  s.write_failures = c.write_failures.load();
  s.samples_lost = c.samples_lost.load();
  s.queue_dropped = c.queue_dropped.load();
  return s;
}

}  // namespace ccm::rt
