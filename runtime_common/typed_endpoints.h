// Typed DataWriter / DataReader wrappers over a DdsSession: QoS from a named XML profile,
// byte and failure counters per topic, matched-endpoint tracking. The reader's listener
// callback only takes samples and enqueues them; the runtime's own thread pops the queue
// and converts. write() returning false is counted and returned, never ignored.
//
// Ownership: created and destroyed by the runtime component that uses them, always before
// their DdsSession. Write()/Pop() may be called from any thread.
#pragma once

#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <limits>
#include <memory>
#include <mutex>
#include <string>

#include "runtime_common/bounded_queue.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/wakeup.h"

namespace ccm::rt {

/// Waits until a matched-count reaches a value; shared by writers and readers. Also counts
/// the matches ever made: more than the peers means a peer was lost and matched again (a
/// TRANSIENT_LOCAL writer then sends its whole history to it once more).
class MatchTracker {
 public:
  void Update(int current, int total) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      matched_ = current;
      total_ = total;
    }
    cv_.notify_all();
  }
  int matched() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return matched_;
  }
  int total() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return total_;
  }
  bool WaitFor(int count, std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return matched_ >= count; });
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  int matched_ = 0, total_ = 0;
};

/// With security, the usual reason an endpoint cannot be created: the permissions.
inline std::string SecurityHint(const DdsSession& session, const std::string& partition) {
  if (session.options().security_dir.empty()) return "";
  return " in partition '" + partition + "': the permissions of '" + session.options().security_dir +
         "' do not allow it (an agent id that is not the certificate's? see the Fast DDS message above)";
}

template <typename PubSubT>
class TypedWriter : public eprosima::fastdds::dds::DataWriterListener {
 public:
  using Msg = typename PubSubT::type;

  /// `partition`: write in this DDS partition only (see DdsSession::publisher); its traffic
  /// is counted as "<topic>@<partition>".
  static std::unique_ptr<TypedWriter> Create(DdsSession& session, const std::string& topic_name,
                                             const std::string& profile, std::string* error,
                                             const std::string& partition = "") {
    namespace dds = eprosima::fastdds::dds;
    std::unique_ptr<TypedWriter> w(
        new TypedWriter(session, partition.empty() ? topic_name : topic_name + "@" + partition));
    w->publisher_ = session.publisher(partition);
    if (w->publisher_ == nullptr) {
      *error = "could not create a publisher in partition '" + partition + "'";
      return nullptr;
    }
    dds::Topic* topic = session.GetTopic(topic_name, w->type_, error);
    if (topic == nullptr) return nullptr;
    dds::DataWriterQos qos;
    if (w->publisher_->get_datawriter_qos_from_profile(profile, qos) != ReturnCode_t::RETCODE_OK) {
      *error = "data writer profile '" + profile + "' not found in '" + session.options().qos_file + "'";
      return nullptr;
    }
    w->writer_ = w->publisher_->create_datawriter(topic, qos, w.get(), dds::StatusMask::publication_matched());
    if (w->writer_ == nullptr) {
      *error = "could not create a data writer on '" + topic_name + "' with profile '" + profile + "'" +
               SecurityHint(session, partition);
      return nullptr;
    }
    return w;
  }

  ~TypedWriter() override {
    if (writer_ != nullptr) publisher_->delete_datawriter(writer_);
  }

  /// Publishes one sample. False when Fast DDS refused it (history full past
  /// max_blocking_time, ...); the failure is counted in the topic's counters.
  bool Write(const Msg& msg) {
    Msg* data = const_cast<Msg*>(&msg);  // Fast DDS' write() takes void*, it does not modify
    const std::uint32_t bytes = type_.get_serialized_size_provider(data)();
    if (!writer_->write(data)) {
      counters_.write_failures++;
      return false;
    }
    counters_.samples++;
    counters_.payload_bytes += bytes;
    return true;
  }

  /// Blocks until every sample written so far is acknowledged by all matched reliable
  /// readers (or the timeout passes).
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) {
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(timeout).count();
    eprosima::fastrtps::Duration_t t(static_cast<int32_t>(ns / 1000000000), static_cast<uint32_t>(ns % 1000000000));
    return writer_->wait_for_acknowledgments(t) == ReturnCode_t::RETCODE_OK;
  }

  int matched() const { return match_.matched(); }
  int matches_ever() const { return match_.total(); }
  bool WaitForMatch(int count, std::chrono::milliseconds timeout) { return match_.WaitFor(count, timeout); }
  const TopicCounters& counters() const { return counters_; }

  /// The bandwidth cap of this writer's profile (`<throughputController>`) in bytes per
  /// second; 0 when it has none. Fast DDS 2.9 shares one such controller among a
  /// participant's capped writers (docs/qos-tuning.md).
  double CapBytesPerSecond() const {
    const auto& c = writer_->get_qos().throughput_controller();
    const bool capped = c.periodMillisecs > 0 && c.bytesPerPeriod > 0 &&
                        c.bytesPerPeriod != std::numeric_limits<decltype(c.bytesPerPeriod)>::max();
    return capped ? 1000.0 * static_cast<double>(c.bytesPerPeriod) / static_cast<double>(c.periodMillisecs) : 0.0;
  }

  void on_publication_matched(eprosima::fastdds::dds::DataWriter*,
                              const eprosima::fastdds::dds::PublicationMatchedStatus& status) override {
    match_.Update(status.current_count, status.total_count);
  }

 private:
  TypedWriter(DdsSession& session, const std::string& topic)
      : session_(session), type_(new PubSubT()), counters_(session.Counters(topic, "out")) {}

  DdsSession& session_;
  eprosima::fastdds::dds::TypeSupport type_;
  TopicCounters& counters_;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::DataWriter* writer_ = nullptr;
  MatchTracker match_;
};

template <typename PubSubT>
class TypedReader : public eprosima::fastdds::dds::DataReaderListener {
 public:
  using Msg = typename PubSubT::type;

  /// One received sample and the writer that sent it (DdsSession::WriterPartition tells the
  /// writer's partition).
  struct Received {
    Msg msg;
    eprosima::fastrtps::rtps::GUID_t writer;
  };

  struct QueueOptions {
    std::size_t capacity = 256;
    OverflowPolicy policy = OverflowPolicy::kDropOldest;
    /// Signalled after samples were queued (a consumer serving several readers waits on it);
    /// must outlive the reader. Optional.
    Wakeup* wakeup = nullptr;
  };

  /// `partition`: read only writers in this DDS partition (see DdsSession::subscriber).
  static std::unique_ptr<TypedReader> Create(DdsSession& session, const std::string& topic_name,
                                             const std::string& profile, QueueOptions queue_options,
                                             std::string* error, const std::string& partition = "") {
    namespace dds = eprosima::fastdds::dds;
    std::unique_ptr<TypedReader> r(new TypedReader(session, topic_name, queue_options));
    dds::Topic* topic = session.GetTopic(topic_name, r->type_, error);
    if (topic == nullptr) return nullptr;
    r->subscriber_ = session.subscriber(partition);
    if (r->subscriber_ == nullptr) {
      *error = "could not create a subscriber in partition '" + partition + "'";
      return nullptr;
    }
    dds::DataReaderQos qos;
    if (r->subscriber_->get_datareader_qos_from_profile(profile, qos) != ReturnCode_t::RETCODE_OK) {
      *error = "data reader profile '" + profile + "' not found in '" + session.options().qos_file + "'";
      return nullptr;
    }
    const dds::StatusMask mask = dds::StatusMask::data_available() << dds::StatusMask::subscription_matched()
                                 << dds::StatusMask::sample_lost();
    r->reader_ = r->subscriber_->create_datareader(topic, qos, r.get(), mask);
    if (r->reader_ == nullptr) {
      *error = "could not create a data reader on '" + topic_name + "' with profile '" + profile + "'" +
               SecurityHint(session, partition);
      return nullptr;
    }
    return r;
  }

  ~TypedReader() override {
    queue_.Close();  // unblocks a listener waiting on a full kBlock queue
    if (reader_ != nullptr) {
      reader_->set_listener(nullptr);
      subscriber_->delete_datareader(reader_);
    }
  }

  /// Next received sample, waiting up to `timeout`.
  std::optional<Msg> Pop(std::chrono::milliseconds timeout) {
    auto r = queue_.Pop(timeout);
    if (!r) return std::nullopt;
    return std::move(r->msg);
  }
  /// Next received sample with its writer, waiting up to `timeout`.
  std::optional<Received> PopWithWriter(std::chrono::milliseconds timeout) { return queue_.Pop(timeout); }
  int matched() const { return match_.matched(); }
  bool WaitForMatch(int count, std::chrono::milliseconds timeout) { return match_.WaitFor(count, timeout); }
  const TopicCounters& counters() const { return counters_; }

  void on_data_available(eprosima::fastdds::dds::DataReader* reader) override {
    eprosima::fastdds::dds::SampleInfo info;
    Received r;
    while (reader->take_next_sample(&r.msg, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      counters_.samples++;
      counters_.payload_bytes += type_.get_serialized_size_provider(&r.msg)();
      r.writer = info.sample_identity.writer_guid();
      const std::size_t dropped_before = queue_.dropped();
      if (!queue_.Push(std::move(r))) return;  // closed: shutting down
      counters_.queue_dropped += queue_.dropped() - dropped_before;
      r = Received();
      if (wakeup_ != nullptr) wakeup_->Signal();
    }
  }
  void on_subscription_matched(eprosima::fastdds::dds::DataReader*,
                               const eprosima::fastdds::dds::SubscriptionMatchedStatus& status) override {
    match_.Update(status.current_count, status.total_count);
  }
  void on_sample_lost(eprosima::fastdds::dds::DataReader*, const eprosima::fastdds::dds::SampleLostStatus& status) override {
    counters_.samples_lost += static_cast<std::uint64_t>(status.total_count_change);
  }

 private:
  TypedReader(DdsSession& session, const std::string& topic, QueueOptions queue_options)
      : session_(session),
        type_(new PubSubT()),
        counters_(session.Counters(topic, "in")),
        queue_(queue_options.capacity, queue_options.policy),
        wakeup_(queue_options.wakeup) {}

  DdsSession& session_;
  eprosima::fastdds::dds::TypeSupport type_;
  TopicCounters& counters_;
  BoundedQueue<Received> queue_;
  Wakeup* const wakeup_;
  eprosima::fastdds::dds::DataReader* reader_ = nullptr;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  MatchTracker match_;
};

}  // namespace ccm::rt
