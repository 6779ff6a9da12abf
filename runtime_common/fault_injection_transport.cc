#include "runtime_common/fault_injection_transport.h"

#include <algorithm>
#include <cstdlib>
#include <sstream>

namespace ccm::rt {

using eprosima::fastrtps::rtps::Locator_t;
using eprosima::fastrtps::rtps::octet;

std::string FaultOptions::Validate() const {
  if (!(drop_probability >= 0.0 && drop_probability < 1.0)) return "drop probability must be in [0, 1)";
  if (!(delay_ms >= 0.0 && delay_ms <= 60000.0)) return "delay must be in [0, 60000] ms";
  if (!(jitter_ms >= 0.0 && jitter_ms <= 60000.0)) return "jitter must be in [0, 60000] ms";
  if (!(outage_at_s >= 0.0 && outage_at_s <= 1e6)) return "the link cut's start must be in [0, 1e6] s";
  if (!(outage_s >= 0.0 && outage_s <= 1e6)) return "the link cut's length must be in [0, 1e6] s";
  if (!(rate_kb_s >= 0.0 && rate_kb_s <= 1e7)) return "the bandwidth cap must be in [0, 1e7] kB/s";
  if (!(queue_ms > 0.0 && queue_ms <= 60000.0)) return "the capped link's buffer must be in (0, 60000] ms";
  return {};
}

namespace {
bool ReadEnvDouble(const char* name, double* out, std::string* error) {
  const char* text = std::getenv(name);
  if (text == nullptr || *text == '\0') return true;
  char* end = nullptr;
  const double value = std::strtod(text, &end);
  if (end == text || *end != '\0') {
    *error = std::string(name) + "='" + text + "' is not a number";
    return false;
  }
  *out = value;
  return true;
}
}  // namespace

std::optional<FaultOptions> FaultOptions::FromEnvironment(std::string* error) {
  FaultOptions options;
  double seed = static_cast<double>(options.seed);
  if (!ReadEnvDouble("CCM_FAULT_DROP", &options.drop_probability, error) ||
      !ReadEnvDouble("CCM_FAULT_DELAY_MS", &options.delay_ms, error) ||
      !ReadEnvDouble("CCM_FAULT_JITTER_MS", &options.jitter_ms, error) ||
      !ReadEnvDouble("CCM_FAULT_SEED", &seed, error) ||
      !ReadEnvDouble("CCM_FAULT_OUTAGE_AT_S", &options.outage_at_s, error) ||
      !ReadEnvDouble("CCM_FAULT_OUTAGE_S", &options.outage_s, error) ||
      !ReadEnvDouble("CCM_FAULT_RATE_KB_S", &options.rate_kb_s, error) ||
      !ReadEnvDouble("CCM_FAULT_QUEUE_MS", &options.queue_ms, error)) {
    return std::nullopt;
  }
  options.seed = static_cast<std::uint64_t>(seed);
  if (const std::string problem = options.Validate(); !problem.empty()) {
    *error = "fault injection from environment: " + problem;
    return std::nullopt;
  }
  return options;
}

std::string FaultOptions::ToString() const {
  std::ostringstream os;
  os << "drop=" << drop_probability << " delay_ms=" << delay_ms << " jitter_ms=" << jitter_ms
     << " seed=" << seed;
  if (outage_s > 0.0) os << " cut=" << outage_at_s << "s+" << outage_s << "s";
  if (rate_kb_s > 0.0) os << " cap=" << rate_kb_s << "kB/s buffer=" << queue_ms << "ms";
  return os.str();
}

FaultInjectionTransportDescriptor::FaultInjectionTransportDescriptor(
    std::shared_ptr<eprosima::fastdds::rtps::TransportDescriptorInterface> low_level,
    FaultOptions fault_options, std::shared_ptr<FaultCounters> fault_counters)
    : ChainingTransportDescriptor(std::move(low_level)),
      options(fault_options),
      counters(fault_counters ? std::move(fault_counters) : std::make_shared<FaultCounters>()) {}

eprosima::fastdds::rtps::TransportInterface* FaultInjectionTransportDescriptor::create_transport() const {
  return new FaultInjectionTransport(*this);
}

FaultInjectionTransport::FaultInjectionTransport(const FaultInjectionTransportDescriptor& descriptor)
    : ChainingTransport(descriptor), descriptor_(descriptor), rng_(descriptor.options.seed) {
  delivery_thread_ = std::thread([this] { DeliveryLoop(); });
}

FaultInjectionTransport::~FaultInjectionTransport() {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stopping_ = true;
  }
  queue_cv_.notify_all();
  delivery_thread_.join();
}

bool FaultInjectionTransport::CloseInputChannel(const Locator_t& locator) {
  // Pending datagrams hold a pointer to this channel's receiver: forget them before the
  // receiver goes away, and never while one of them is being delivered.
  {
    std::lock_guard<std::mutex> deliver_lock(deliver_mutex_);
    std::lock_guard<std::mutex> lock(queue_mutex_);
    decltype(queue_) kept;
    while (!queue_.empty()) {
      if (!(queue_.top().local_locator == locator)) kept.push(queue_.top());
      queue_.pop();
    }
    queue_.swap(kept);
  }
  return ChainingTransport::CloseInputChannel(locator);
}

bool FaultInjectionTransport::send(eprosima::fastrtps::rtps::SenderResource* low_sender_resource,
                                   const octet* send_buffer, uint32_t send_buffer_size,
                                   eprosima::fastrtps::rtps::LocatorsIterator* destination_locators_begin,
                                   eprosima::fastrtps::rtps::LocatorsIterator* destination_locators_end,
                                   const std::chrono::steady_clock::time_point& timeout) {
  if (InOutage(std::chrono::steady_clock::now())) {  // cut off: the datagram never leaves
    descriptor_.counters->datagrams_cut++;
    return true;
  }
  return low_sender_resource->send(send_buffer, send_buffer_size, destination_locators_begin,
                                   destination_locators_end, timeout);
}

void FaultInjectionTransport::receive(eprosima::fastdds::rtps::TransportReceiverInterface* next_receiver,
                                      const octet* receive_buffer, uint32_t receive_buffer_size,
                                      const Locator_t& local_locator, const Locator_t& remote_locator) {
  FaultCounters& counters = *descriptor_.counters;
  counters.datagrams_received++;
  counters.bytes_received += receive_buffer_size;
  if (!counters.watch_pattern.empty() &&
      std::search(receive_buffer, receive_buffer + receive_buffer_size, counters.watch_pattern.begin(),
                  counters.watch_pattern.end()) != receive_buffer + receive_buffer_size) {
    counters.watch_hits++;
  }
  const FaultOptions& options = descriptor_.options;
  const auto now = std::chrono::steady_clock::now();
  if (InOutage(now)) {
    counters.datagrams_cut++;
    counters.datagrams_dropped++;
    return;
  }
  double delay_ms = options.delay_ms;
  auto arrival = now;  // when the datagram has come through the (capped) link
  {
    std::lock_guard<std::mutex> lock(rng_mutex_);
    if (options.drop_probability > 0.0 &&
        std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < options.drop_probability) {
      counters.datagrams_dropped++;
      return;
    }
    if (options.jitter_ms > 0.0) delay_ms += std::uniform_real_distribution<double>(0.0, options.jitter_ms)(rng_);
    if (options.rate_kb_s > 0.0) {
      // One link of rate_kb_s: a datagram starts when the ones before it are through; one
      // that would wait more than the buffer holds is dropped (tail drop).
      const auto start = std::max(now, link_free_);
      if (start - now > std::chrono::duration<double, std::milli>(options.queue_ms)) {
        counters.datagrams_over_cap++;
        counters.datagrams_dropped++;
        return;
      }
      link_free_ = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                               std::chrono::duration<double>(receive_buffer_size / (options.rate_kb_s * 1000.0)));
      arrival = link_free_;
    }
  }
  if (delay_ms <= 0.0 && arrival <= now) {
    next_receiver->OnDataReceived(receive_buffer, receive_buffer_size, local_locator, remote_locator);
    return;
  }
  Pending pending;
  pending.due = arrival + std::chrono::microseconds(static_cast<std::int64_t>(delay_ms * 1000.0));
  pending.receiver = next_receiver;
  pending.data.assign(receive_buffer, receive_buffer + receive_buffer_size);
  pending.local_locator = local_locator;
  pending.remote_locator = remote_locator;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    if (stopping_) return;
    pending.sequence = next_sequence_++;
    queue_.push(std::move(pending));
  }
  queue_cv_.notify_one();
}

bool FaultInjectionTransport::InOutage(std::chrono::steady_clock::time_point now) const {
  const FaultOptions& o = descriptor_.options;
  if (o.outage_s <= 0.0) return false;
  const double t = std::chrono::duration<double>(now - created_).count();
  return t >= o.outage_at_s && t < o.outage_at_s + o.outage_s;
}

void FaultInjectionTransport::DeliveryLoop() {
  for (;;) {
    std::unique_lock<std::mutex> deliver_lock(deliver_mutex_);
    std::unique_lock<std::mutex> lock(queue_mutex_);
    if (stopping_) return;
    if (queue_.empty()) {
      deliver_lock.unlock();  // keep lock order: never wait holding deliver_mutex_ alone
      queue_cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      continue;
    }
    const auto due = queue_.top().due;
    if (std::chrono::steady_clock::now() < due) {
      deliver_lock.unlock();
      queue_cv_.wait_until(lock, due);
      continue;
    }
    Pending pending = queue_.top();
    queue_.pop();
    lock.unlock();
    pending.receiver->OnDataReceived(pending.data.data(), static_cast<uint32_t>(pending.data.size()),
                                     pending.local_locator, pending.remote_locator);
  }
}

}  // namespace ccm::rt
