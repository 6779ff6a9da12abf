#include "runtime_common/dds_session.h"

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/builtin/data/WriterProxyData.h>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <fstream>

#include "slam_core/common/install_paths.h"

#ifndef CCM_QOS_DIR
#define CCM_QOS_DIR "qos_profiles"
#endif

namespace ccm::rt {

namespace dds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastdds::rtps;

bool LoadQosFile(const std::string& path, std::string* error) {
  // Fast DDS keeps profiles process-wide and refuses to load a profile name twice, so each
  // file is loaded once per process. Two different files defining the same profile names
  // cannot be used in one process (one binary = one --qos file).
  static std::mutex mutex;
  static std::set<std::string> loaded;
  std::lock_guard<std::mutex> lock(mutex);
  std::error_code ec;
  const std::string canonical = std::filesystem::weakly_canonical(path, ec).string();
  if (loaded.count(canonical) != 0) return true;
  if (!std::ifstream(path).good()) {
    *error = "QoS file '" + path + "' does not exist or cannot be read";
    return false;
  }
  if (!loaded.empty()) {
    *error = "QoS file '" + path + "' cannot be loaded: this process already uses '" + *loaded.begin() +
             "' (profile names would clash; use one QoS file per process)";
    return false;
  }
  if (dds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(path) != ReturnCode_t::RETCODE_OK) {
    dds::Log::Flush();  // Fast DDS logs asynchronously: its parser messages first, then ours
    *error = "QoS file '" + path +
             "' was rejected by the Fast DDS 2.9 XML parser (see the parser message above; one unknown "
             "element rejects the whole file)";
    return false;
  }
  loaded.insert(canonical);
  return true;
}

std::string DefaultQosFile() {
  if (const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE"); env != nullptr && *env != '\0') {
    return env;
  }
  return FindDataFile("qos_profiles/default.xml", std::string(CCM_QOS_DIR) + "/default.xml");
}

int AgentIdOfParticipantName(const std::string& name) {
  static const std::string prefix = "ccm_";
  return name.compare(0, prefix.size(), prefix) == 0 ? AgentIdOfPartition(name.substr(prefix.size())) : -1;
}

int AgentIdOfPartition(const std::string& partition) {
  static const std::string prefix = "agent_";
  if (partition.size() <= prefix.size() || partition.size() > prefix.size() + 5 ||
      partition.compare(0, prefix.size(), prefix) != 0) {
    return -1;
  }
  // One spelling per agent: "agent_01" would name agent 1 from a partition that its
  // permissions (granted for "agent_1") do not cover.
  if (partition[prefix.size()] == '0') return -1;
  int id = 0;
  for (size_t i = prefix.size(); i < partition.size(); ++i) {
    if (partition[i] < '0' || partition[i] > '9') return -1;
    id = id * 10 + (partition[i] - '0');
  }
  return id >= 1 && id <= 65535 ? id : -1;
}

bool ApplySecurity(const SessionOptions& options, dds::DomainParticipantQos* qos, std::string* error) {
  if (options.security_dir.empty()) return true;
  // Fast DDS 2.9.1 sends each authentication handshake message (certificate + signed
  // permissions, ~5 kB) in ONE datagram: it does not fragment builtin messages. With a
  // smaller maxMessageSize the handshake fails silently ("Cannot serialize
  // ParticipantGenericMessage") and nothing ever matches; say so up front instead.
  // Measured: 4500 B fails, 6000 B works; 8192 leaves room for longer permissions.
  constexpr uint32_t kMinSecureMessageSize = 8192;
  for (const auto& transport : qos->transport().user_transports) {
    if (transport->maxMessageSize < kMinSecureMessageSize) {
      *error = "security: the QoS file's transport has maxMessageSize " + std::to_string(transport->maxMessageSize) +
               " B; the secure handshake needs >= " + std::to_string(kMinSecureMessageSize) +
               " B (Fast DDS 2.9 does not fragment it; docs/security.md, 'Wi-Fi')";
      return false;
    }
  }
  // The security profile lives in its own file (plugins only, no endpoint QoS), so it adds
  // to whichever QoS file the binary uses (default.xml, wifi.xml, ...). Its profile names
  // do not clash with those files', so loading it next to them is safe (once per process).
  const std::string file = options.security_file.empty() ? std::string(CCM_QOS_DIR) + "/secure.xml"
                                                         : options.security_file;
  {
    static std::mutex mutex;
    static std::set<std::string> loaded;
    std::lock_guard<std::mutex> lock(mutex);
    if (loaded.count(file) == 0) {
      if (!std::ifstream(file).good()) {
        *error = "security profile file '" + file + "' does not exist or cannot be read";
        return false;
      }
      if (dds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(file) != ReturnCode_t::RETCODE_OK) {
        *error = "security profile file '" + file + "' was rejected by the Fast DDS XML parser";
        return false;
      }
      loaded.insert(file);
    }
  }
  dds::DomainParticipantQos secure;
  if (dds::DomainParticipantFactory::get_instance()->get_participant_qos_from_profile(options.security_profile,
                                                                                      secure) !=
      ReturnCode_t::RETCODE_OK) {
    *error = "participant profile '" + options.security_profile + "' not found in '" + file + "'";
    return false;
  }
  // The profile's own properties only: both QoS carry Fast DDS' defaults (physical_data.*).
  auto& properties = qos->properties().properties();
  for (const auto& property : secure.properties().properties()) {
    const bool present = std::any_of(properties.begin(), properties.end(),
                                     [&](const auto& p) { return p.name() == property.name(); });
    if (!present) properties.push_back(property);
  }
  // The six files of one participant, as deploy/security/make-pki.sh lays them out.
  const std::filesystem::path dir = std::filesystem::absolute(options.security_dir).lexically_normal();
  const std::pair<const char*, const char*> files[] = {
      {"dds.sec.auth.builtin.PKI-DH.identity_ca", "identity_ca.pem"},
      {"dds.sec.auth.builtin.PKI-DH.identity_certificate", "cert.pem"},
      {"dds.sec.auth.builtin.PKI-DH.private_key", "key.pem"},
      {"dds.sec.access.builtin.Access-Permissions.permissions_ca", "permissions_ca.pem"},
      {"dds.sec.access.builtin.Access-Permissions.governance", "governance.p7s"},
      {"dds.sec.access.builtin.Access-Permissions.permissions", "permissions.p7s"}};
  for (const auto& [property, name] : files) {
    const std::filesystem::path path = dir / name;
    if (!std::ifstream(path).good()) {
      *error = "security: '" + path.string() + "' does not exist or cannot be read (security_dir '" +
               options.security_dir + "' must hold what deploy/security/make-pki.sh writes for this participant)";
      return false;
    }
    qos->properties().properties().emplace_back(property, "file://" + path.string());
  }
  // Optional: the CA's list of revoked certificates (make-pki.sh --revoke).
  if (const std::filesystem::path crl = dir / "identity_crl.pem"; std::filesystem::exists(crl)) {
    qos->properties().properties().emplace_back("dds.sec.auth.builtin.PKI-DH.identity_crl", "file://" + crl.string());
  }
  return true;
}

namespace {

// Wraps every UDPv4 transport of the profile into the fault-injection transport and drops
// shared memory (same-host traffic would otherwise bypass the faults).
void InstallFaultTransport(dds::DomainParticipantQos* qos, const FaultOptions& fault,
                           const std::shared_ptr<FaultCounters>& counters) {
  auto& transport = qos->transport();
  std::vector<std::shared_ptr<rtps::TransportDescriptorInterface>> wrapped;
  for (const auto& descriptor : transport.user_transports) {
    if (std::dynamic_pointer_cast<rtps::UDPv4TransportDescriptor>(descriptor)) {
      wrapped.push_back(std::make_shared<FaultInjectionTransportDescriptor>(descriptor, fault, counters));
    } else if (!std::dynamic_pointer_cast<rtps::SharedMemTransportDescriptor>(descriptor)) {
      wrapped.push_back(descriptor);
    }
  }
  if (transport.use_builtin_transports || wrapped.empty()) {
    wrapped.push_back(std::make_shared<FaultInjectionTransportDescriptor>(
        std::make_shared<rtps::UDPv4TransportDescriptor>(), fault, counters));
  }
  transport.user_transports = wrapped;
  transport.use_builtin_transports = false;
}

}  // namespace

DdsSession::DdsSession(SessionOptions options) : options_(std::move(options)) {}

std::unique_ptr<DdsSession> DdsSession::Create(const SessionOptions& options, std::string* error) {
  if (const std::string problem = options.fault.Validate(); !problem.empty()) {
    *error = "fault injection: " + problem;
    return nullptr;
  }
  const std::string qos_file = options.qos_file.empty() ? DefaultQosFile() : options.qos_file;
  if (!LoadQosFile(qos_file, error)) return nullptr;
  auto* factory = dds::DomainParticipantFactory::get_instance();
  dds::DomainParticipantQos qos;
  if (factory->get_participant_qos_from_profile(options.participant_profile, qos) != ReturnCode_t::RETCODE_OK) {
    *error = "participant profile '" + options.participant_profile + "' not found in '" + qos_file + "'";
    return nullptr;
  }
  qos.name(options.participant_name);
  if (!ApplySecurity(options, &qos, error)) return nullptr;
  std::unique_ptr<DdsSession> session(new DdsSession(options));
  session->options_.qos_file = qos_file;
  session->fault_counters_->watch_pattern = options.wire_watch_pattern;
  if (options.fault.enabled() || options.count_wire) InstallFaultTransport(&qos, options.fault, session->fault_counters_);
  // The listener only records discovered writers' partitions; no status callbacks.
  session->participant_ =
      factory->create_participant(options.domain_id, qos, session.get(), dds::StatusMask::none());
  if (session->participant_ == nullptr) {
    *error = "could not create the DDS participant on domain " + std::to_string(options.domain_id);
    if (!options.security_dir.empty()) {
      *error += " with security from '" + options.security_dir +
                "' (see the Fast DDS security messages above: a key that does not match the certificate, a "
                "certificate or document not signed by the given CA, or expired permissions)";
    }
    return nullptr;
  }
  session->publisher_ = session->participant_->create_publisher(dds::PUBLISHER_QOS_DEFAULT);
  session->subscriber_ = session->participant_->create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT);
  if (session->publisher_ == nullptr || session->subscriber_ == nullptr) {
    *error = "could not create the DDS publisher/subscriber";
    return nullptr;
  }
  return session;
}

DdsSession::~DdsSession() {
  if (participant_ == nullptr) return;
  participant_->set_listener(nullptr);
  // Endpoints were deleted by their owners; what is left (publisher, subscriber, topics)
  // goes with the participant.
  participant_->delete_contained_entities();
  dds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

dds::Publisher* DdsSession::publisher(const std::string& partition) {
  if (partition.empty()) return publisher_;
  std::lock_guard<std::mutex> lock(mutex_);
  auto& p = partition_publishers_[partition];
  if (p == nullptr) {
    dds::PublisherQos qos = dds::PUBLISHER_QOS_DEFAULT;
    qos.partition().push_back(partition.c_str());
    p = participant_->create_publisher(qos);
  }
  return p;
}

dds::Subscriber* DdsSession::subscriber(const std::string& partition) {
  if (partition.empty()) return subscriber_;
  std::lock_guard<std::mutex> lock(mutex_);
  auto& s = partition_subscribers_[partition];
  if (s == nullptr) {
    dds::SubscriberQos qos = dds::SUBSCRIBER_QOS_DEFAULT;
    qos.partition().push_back(partition.c_str());
    s = participant_->create_subscriber(qos);
  }
  return s;
}

dds::Topic* DdsSession::GetTopic(const std::string& name, dds::TypeSupport type, std::string* error) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto it = topics_.find(name); it != topics_.end()) return it->second;
  const std::string type_name = type.get_type_name();
  if (participant_->find_type(type_name).empty() && type.register_type(participant_) != ReturnCode_t::RETCODE_OK) {
    *error = "could not register type " + type_name;
    return nullptr;
  }
  dds::Topic* topic = participant_->create_topic(name, type_name, dds::TOPIC_QOS_DEFAULT);
  if (topic == nullptr) {
    *error = "could not create topic " + name;
    return nullptr;
  }
  topics_[name] = topic;
  return topic;
}

void DdsSession::on_publisher_discovery(dds::DomainParticipant*, eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) {
  using Status = eprosima::fastrtps::rtps::WriterDiscoveryInfo;
  std::lock_guard<std::mutex> lock(writers_mutex_);
  if (info.status == Status::REMOVED_WRITER) {
    writer_partitions_.erase(info.info.guid());
    return;
  }
  const auto& partition = info.info.m_qos.m_partition;
  writer_partitions_[info.info.guid()] = partition.begin() != partition.end() ? partition.begin()->name() : "";
}

void DdsSession::on_participant_discovery(dds::DomainParticipant*,
                                          eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) {
  using Status = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
  if (!options_.track_agent_participants || info.status != Status::DISCOVERED_PARTICIPANT) return;
  const int id = AgentIdOfParticipantName(info.info.m_participantName.to_string());
  if (id < 0) return;
  std::lock_guard<std::mutex> lock(writers_mutex_);
  if (discovered_agents_.size() < 1024) discovered_agents_.push_back(id);  // bounded against floods
}

std::vector<int> DdsSession::TakeDiscoveredAgents() {
  std::lock_guard<std::mutex> lock(writers_mutex_);
  std::vector<int> out;
  out.swap(discovered_agents_);
  return out;
}

std::optional<std::string> DdsSession::WriterPartition(const eprosima::fastrtps::rtps::GUID_t& writer) const {
  std::lock_guard<std::mutex> lock(writers_mutex_);
  auto it = writer_partitions_.find(writer);
  if (it == writer_partitions_.end()) return std::nullopt;
  return it->second;
}

TopicCounters& DdsSession::Counters(const std::string& topic, const std::string& direction) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto& slot = counters_[{topic, direction}];
  if (!slot) slot = std::make_unique<TopicCounters>();
  return *slot;
}

std::vector<TopicCountersSnapshot> DdsSession::TrafficSnapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<TopicCountersSnapshot> out;
  for (const auto& [key, counters] : counters_) out.push_back(Snapshot(key.first, key.second, *counters));
  return out;
}

}  // namespace ccm::rt
