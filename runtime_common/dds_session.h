// One DDS participant of a runtime (agent or server) plus its publisher, subscriber and
// topics. All QoS comes from XML profiles selected by name (qos_profiles/*.xml); the only
// thing changed in code is the transport, and only when fault injection is requested.
//
// Ownership: the runtime owns the session; writers/readers created from it must be
// destroyed before it (they hold raw pointers to its publisher/subscriber). All methods
// may be called from any thread; creation/destruction of endpoints is serialized inside.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>
#include <cstdint>

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
  /// With count_wire: also count received datagrams that contain this byte sequence
  /// (FaultCounters::watch_hits; tests look for a keyframe's bytes on the wire).
  std::vector<std::uint8_t> wire_watch_pattern;
  /// DDS-Security (docs/security.md): a directory laid out by deploy/security/make-pki.sh
  /// (identity_ca.pem, cert.pem, key.pem, permissions_ca.pem, governance.p7s,
  /// permissions.p7s). Empty: no security. The plugins come from the participant profile
  /// `security_profile` of `security_file`; only the file paths are set here.
  std::string security_dir;
  /// Empty: the installed/source-tree qos_profiles/secure.xml.
  std::string security_file;
  std::string security_profile = "ccm_secure_participant";
  /// Record agents' participants as they are discovered (TakeDiscoveredAgents): the server
  /// only; other processes would collect ids nobody reads.
  bool track_agent_participants = false;
};

/// Loads an XML profiles file with a clear error for a missing file or a parse failure.
bool LoadQosFile(const std::string& path, std::string* error);
/// The QoS file a binary uses when none is given: $FASTRTPS_DEFAULT_PROFILES_FILE if set,
/// otherwise the installed (install_paths.h) or source-tree default.xml.
std::string DefaultQosFile();
/// Adds the DDS-Security properties to a participant's QoS: the plugin properties of
/// `options.security_profile` (from options.security_file) and the six file paths in
/// `options.security_dir`. Clear error for a missing file or profile. No-op without a dir.
bool ApplySecurity(const SessionOptions& options, eprosima::fastdds::dds::DomainParticipantQos* qos,
                   std::string* error);
/// "agent_<id>" -> id; -1 for anything else (runtime_common/topics.h AgentPartition).
int AgentIdOfPartition(const std::string& partition);
/// "ccm_agent_<id>" (ccm_agent's participant name) -> id; -1 for anything else.
int AgentIdOfParticipantName(const std::string& name);

class DdsSession : private eprosima::fastdds::dds::DomainParticipantListener {
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
  /// The first DDS partition of a discovered remote writer ("" for the default partition,
  /// nullopt if it is not (yet) known). Filled by discovery, so a receiver can tell which
  /// partition a sample came from (SampleInfo only names the writer).
  std::optional<std::string> WriterPartition(const eprosima::fastrtps::rtps::GUID_t& writer) const;
  /// Ids of agents whose participant ("ccm_agent_<id>") was discovered since the last call.
  /// The server creates an agent's writers then, so their endpoint discovery runs alongside
  /// the agent's own instead of after its first data (at 50 % loss each took ~15 s).
  /// The name is only a hint: it grants nothing. Empty unless the session was created with
  /// track_agent_participants.
  std::vector<int> TakeDiscoveredAgents();

 private:
  explicit DdsSession(SessionOptions options);
  // DomainParticipantListener (discovery thread): records writers' partitions and, with
  // track_agent_participants, agents' participants.
  void on_publisher_discovery(eprosima::fastdds::dds::DomainParticipant* participant,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override;
  void on_participant_discovery(eprosima::fastdds::dds::DomainParticipant* participant,
                                eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override;

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
  mutable std::mutex writers_mutex_;  // guards writer_partitions_; leaf
  std::map<eprosima::fastrtps::rtps::GUID_t, std::string> writer_partitions_;
  std::vector<int> discovered_agents_;  // guarded by writers_mutex_
};

}  // namespace ccm::rt
