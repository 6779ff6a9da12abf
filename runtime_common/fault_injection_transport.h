// In-process network fault injection (Linux netem is not available here): a Fast DDS
// ChainingTransport that wraps the real UDPv4 transport and, for every datagram this
// participant RECEIVES, drops it with probability `drop_probability` and delivers the rest
// after `delay_ms` (+ uniform jitter) from a delivery thread owned by the transport.
// Receive-side injection covers both directions of a link as soon as both peers enable it
// (data one way, ACKNACK/heartbeats the other way). Discovery traffic is affected too,
// exactly as on a real lossy link.
// Two more faults for the chaos tests (issue 28): a link cut (an outage window in which this
// participant neither sends nor receives anything: one process is cut off from everyone) and
// a bandwidth cap on what it receives (datagrams queue behind a link of that rate with a
// bounded buffer, and are dropped when the buffer is full, as at a saturated access point).
#pragma once

#include <fastdds/rtps/transport/ChainingTransport.h>
#include <fastdds/rtps/transport/ChainingTransportDescriptor.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <queue>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace ccm::rt {

struct FaultOptions {
  double drop_probability = 0.0;  // [0, 1): probability that one received datagram is lost
  double delay_ms = 0.0;          // one-way delay added to every delivered datagram
  double jitter_ms = 0.0;         // uniform extra delay in [0, jitter_ms]
  std::uint64_t seed = 1;         // random seed (fault pattern reproducible per process)
  double outage_at_s = 0.0;       // link cut: starts this long after the participant was created
  double outage_s = 0.0;          // ... and lasts this long: nothing sent or received (0: no cut)
  double rate_kb_s = 0.0;         // cap on received bytes [kB/s] (0: none)
  double queue_ms = 500.0;        // the capped link's buffer: a datagram that would wait longer is dropped

  bool enabled() const {
    return drop_probability > 0.0 || delay_ms > 0.0 || jitter_ms > 0.0 || outage_s > 0.0 || rate_kb_s > 0.0;
  }
  /// Empty string when valid, otherwise what is wrong.
  std::string Validate() const;
  /// Reads CCM_FAULT_DROP, CCM_FAULT_DELAY_MS, CCM_FAULT_JITTER_MS, CCM_FAULT_SEED,
  /// CCM_FAULT_OUTAGE_AT_S, CCM_FAULT_OUTAGE_S, CCM_FAULT_RATE_KB_S, CCM_FAULT_QUEUE_MS.
  /// Unset variables keep the defaults; malformed values yield an error message.
  static std::optional<FaultOptions> FromEnvironment(std::string* error);
  std::string ToString() const;
};

/// Counters of every datagram that reached one participant (before the drop decision).
/// Wire traffic is measured on arrival: on the send side Fast DDS hands each datagram to
/// every sender resource (one per interface), which would count it several times.
struct FaultCounters {
  std::atomic<std::uint64_t> datagrams_received{0};
  std::atomic<std::uint64_t> datagrams_dropped{0};
  std::atomic<std::uint64_t> bytes_received{0};
  std::atomic<std::uint64_t> datagrams_cut{0};     // received or sent during the link cut, never delivered
  std::atomic<std::uint64_t> datagrams_over_cap{0};  // received while the capped link's buffer was full
  /// Optional probe (set before the participant exists, never changed after): received
  /// datagrams that contain this byte sequence are counted in watch_hits. Tests use it to
  /// check whether a keyframe's bytes are readable on the wire (docs/security.md).
  std::vector<std::uint8_t> watch_pattern;
  std::atomic<std::uint64_t> watch_hits{0};
};

class FaultInjectionTransportDescriptor : public eprosima::fastdds::rtps::ChainingTransportDescriptor {
 public:
  FaultInjectionTransportDescriptor(
      std::shared_ptr<eprosima::fastdds::rtps::TransportDescriptorInterface> low_level,
      FaultOptions options, std::shared_ptr<FaultCounters> counters);
  eprosima::fastdds::rtps::TransportInterface* create_transport() const override;

  FaultOptions options;
  std::shared_ptr<FaultCounters> counters;
};

class FaultInjectionTransport : public eprosima::fastdds::rtps::ChainingTransport {
 public:
  explicit FaultInjectionTransport(const FaultInjectionTransportDescriptor& descriptor);
  ~FaultInjectionTransport() override;

  eprosima::fastdds::rtps::TransportDescriptorInterface* get_configuration() override {
    return &descriptor_;
  }
  bool CloseInputChannel(const eprosima::fastrtps::rtps::Locator_t& locator) override;

  bool send(eprosima::fastrtps::rtps::SenderResource* low_sender_resource,
            const eprosima::fastrtps::rtps::octet* send_buffer, uint32_t send_buffer_size,
            eprosima::fastrtps::rtps::LocatorsIterator* destination_locators_begin,
            eprosima::fastrtps::rtps::LocatorsIterator* destination_locators_end,
            const std::chrono::steady_clock::time_point& timeout) override;

  void receive(eprosima::fastdds::rtps::TransportReceiverInterface* next_receiver,
               const eprosima::fastrtps::rtps::octet* receive_buffer, uint32_t receive_buffer_size,
               const eprosima::fastrtps::rtps::Locator_t& local_locator,
               const eprosima::fastrtps::rtps::Locator_t& remote_locator) override;

 private:
  struct Pending {
    std::chrono::steady_clock::time_point due;
    std::uint64_t sequence;  // FIFO among equal due times
    eprosima::fastdds::rtps::TransportReceiverInterface* receiver;
    std::vector<eprosima::fastrtps::rtps::octet> data;
    eprosima::fastrtps::rtps::Locator_t local_locator;
    eprosima::fastrtps::rtps::Locator_t remote_locator;
    bool operator>(const Pending& o) const {
      return due != o.due ? due > o.due : sequence > o.sequence;
    }
  };

  void DeliveryLoop();
  bool InOutage(std::chrono::steady_clock::time_point now) const;

  FaultInjectionTransportDescriptor descriptor_;
  const std::chrono::steady_clock::time_point created_ = std::chrono::steady_clock::now();
  std::mutex rng_mutex_;  // guards rng_ and link_free_; leaf
  std::mt19937_64 rng_;
  std::chrono::steady_clock::time_point link_free_{};  // when the capped link has sent all it queued
  // Lock order: deliver_mutex_ before queue_mutex_ (CloseInputChannel takes both).
  std::mutex deliver_mutex_;
  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::priority_queue<Pending, std::vector<Pending>, std::greater<Pending>> queue_;
  std::uint64_t next_sequence_ = 0;
  bool stopping_ = false;
  std::thread delivery_thread_;  // owned here: started in the constructor, joined in the destructor
};

}  // namespace ccm::rt
