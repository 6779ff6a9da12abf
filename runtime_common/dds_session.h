// One DDS participant of a runtime (agent or server) plus its publisher, subscriber and
// topics. All QoS comes from XML profiles selected by name (qos_profiles/*.xml); the only
// thing changed in code is the transport, and only when fault injection is requested.
//
// Ownership: the runtime owns the session; writers/readers created from it must be
// destroyed before it (they hold raw pointers to its publisher/subscriber). All methods
// may be called from any thread; creation/destruction of endpoints is serialized inside.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "runtime_common/fault_injection_transport.h"
#include "runtime_common/traffic_stats.h"

namespace ccm::rt {

struct SessionOptions {
  int domain_id = 0;
  /// XML file with the profiles. Empty: FASTRTPS_DEFAULT_PROFILES_FILE (loaded by Fast DDS
  /// itself) or, failing that, the shipped qos_profiles/default.xml.
  std::string qos_file;
  std::string participant_profile = "ccm_participant";
  std::string participant_name = "ccm";
  FaultOptions fault;
  /// Install the (pass-through) fault transport even without faults, to count datagrams
  /// and bytes on the wire (benchmarks, diagnostics).
  bool count_wire = false;
};

/// Loads an XML profiles file with a clear error for a missing file or a parse failure.
bool LoadQosFile(const std::string& path, std::string* error);
/// The QoS file a binary uses when none is given: $FASTRTPS_DEFAULT_PROFILES_FILE if set,
/// otherwise the installed (install_paths.h) or source-tree default.xml.
std::string DefaultQosFile();

class DdsSession {
 public:
  static std::unique_ptr<DdsSession> Create(const SessionOptions& options, std::string* error);
  ~DdsSession();
  DdsSession(const DdsSession&) = delete;
  DdsSession& operator=(const DdsSession&) = delete;

  /// Finds or creates the topic `name` of the given type (registers the type once).
  eprosima::fastdds::dds::Topic* GetTopic(const std::string& name,
                                          eprosima::fastdds::dds::TypeSupport type, std::string* error);
  eprosima::fastdds::dds::DomainParticipant* participant() { return participant_; }
  eprosima::fastdds::dds::Publisher* publisher() { return publisher_; }
  eprosima::fastdds::dds::Subscriber* subscriber() { return subscriber_; }
  /// A publisher / subscriber in one DDS partition, created on first use (nullptr if Fast
  /// DDS refuses). Endpoints only match within a partition: the server's per-agent writers
  /// reach exactly one agent's reader ("agent_<id>").
  eprosima::fastdds::dds::Publisher* publisher(const std::string& partition);
  eprosima::fastdds::dds::Subscriber* subscriber(const std::string& partition);

  /// Counters for one topic and direction ("out"/"in"), created on first use.
  TopicCounters& Counters(const std::string& topic, const std::string& direction);
  std::vector<TopicCountersSnapshot> TrafficSnapshot() const;
  /// Datagram counters of the fault-injection transport (all zero when it is off).
  const FaultCounters& fault_counters() const { return *fault_counters_; }
  const SessionOptions& options() const { return options_; }

 private:
  explicit DdsSession(SessionOptions options);

  SessionOptions options_;
  std::shared_ptr<FaultCounters> fault_counters_ = std::make_shared<FaultCounters>();
  eprosima::fastdds::dds::DomainParticipant* participant_ = nullptr;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  mutable std::mutex mutex_;  // guards topics_, counters_ (the maps, not the counters) and the partition maps
  std::map<std::string, eprosima::fastdds::dds::Topic*> topics_;
  std::map<std::string, eprosima::fastdds::dds::Publisher*> partition_publishers_;
  std::map<std::string, eprosima::fastdds::dds::Subscriber*> partition_subscribers_;
  std::map<std::pair<std::string, std::string>, std::unique_ptr<TopicCounters>> counters_;
};

}  // namespace ccm::rt
