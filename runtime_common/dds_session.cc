#include "runtime_common/dds_session.h"

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>

#include <cstdlib>
#include <filesystem>
#include <set>
#include <fstream>

#include "runtime_common/install_paths.h"

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
  std::unique_ptr<DdsSession> session(new DdsSession(options));
  session->options_.qos_file = qos_file;
  if (options.fault.enabled() || options.count_wire) InstallFaultTransport(&qos, options.fault, session->fault_counters_);
  session->participant_ = factory->create_participant(options.domain_id, qos);
  if (session->participant_ == nullptr) {
    *error = "could not create the DDS participant on domain " + std::to_string(options.domain_id);
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
