// Is a keyframe readable on the wire? Two participants in this process (an agent writing
// keyframes in its partition, the server reading them) exchange synthetic keyframes over UDP
// loopback; the server's fault-injection transport looks for 24 bytes of one keyframe's
// ORB descriptors in every datagram it receives. Without security they are there; with the
// secure profile and the governance of deploy/security/make-pki.sh (payload encrypted) they
// are not, while every keyframe still arrives intact. Also: a directory that misses a file
// is refused with a message naming it.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>

#include <filesystem>
#include <set>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/synthetic_msgs.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"

namespace ccm {
namespace {

const std::string& Pki() {
  static const std::string dir = [] {
    const std::string d = ::testing::TempDir() + "/secure_wire_pki";
    std::filesystem::remove_all(d);
    const std::string cmd = std::string(CCM_MAKE_PKI) + " " + d + " --agents 1 > " + d + ".log 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    return d;
  }();
  return dir;
}

struct WireResult {
  int received = 0, intact = 0;
  std::uint64_t watch_hits = 0, datagrams = 0;
};

WireResult SendKeyframes(bool secure, int domain) {
  constexpr int kKeyframes = 10;
  std::vector<msg::KeyframeFull> sent;
  for (int i = 0; i < kKeyframes; ++i) sent.push_back(synthetic::MakeKeyframe(1, i, 500, 100));
  const auto& d = sent[3].descriptors()[17].data();
  rt::SessionOptions options;
  options.qos_file = std::string(CCM_QOS_DIR) + "/default.xml";
  options.domain_id = domain;
  options.count_wire = true;
  rt::SessionOptions server_options = options;
  server_options.wire_watch_pattern.assign(d.begin(), d.begin() + 24);
  if (secure) {
    options.security_dir = Pki() + "/agent_1";
    server_options.security_dir = Pki() + "/server";
  }
  std::string error;
  auto server = rt::DdsSession::Create(server_options, &error);
  EXPECT_TRUE(server) << error;
  auto agent = server ? rt::DdsSession::Create(options, &error) : nullptr;
  EXPECT_TRUE(agent) << error;
  WireResult r;
  if (!agent) return r;
  auto reader = rt::TypedReader<msg::KeyframeFullPubSubType>::Create(
      *server, rt::kTopicKeyframes, rt::kProfileNewDataReader, {64, rt::OverflowPolicy::kBlock}, &error,
      rt::kAllAgentsPartition);
  auto writer = rt::TypedWriter<msg::KeyframeFullPubSubType>::Create(*agent, rt::kTopicKeyframes,
                                                                     rt::kProfileNewDataWriter, &error,
                                                                     rt::AgentPartition(1));
  EXPECT_TRUE(reader && writer) << error;
  if (!reader || !writer) return r;
  EXPECT_TRUE(writer->WaitForMatch(1, std::chrono::seconds(20)));
  for (const auto& kf : sent) EXPECT_TRUE(writer->Write(kf));
  while (r.received < kKeyframes) {
    auto got = reader->Pop(std::chrono::seconds(10));
    if (!got) break;
    r.intact += *got == sent[static_cast<size_t>(r.received)] ? 1 : 0;
    ++r.received;
  }
  r.watch_hits = server->fault_counters().watch_hits.load();
  r.datagrams = server->fault_counters().datagrams_received.load();
  return r;
}

TEST(SecureWire, KeyframeBytesAreOnThePlainWireAndNotOnTheSecureOne) {
  const WireResult plain = SendKeyframes(false, 175);
  EXPECT_EQ(plain.received, 10);
  EXPECT_EQ(plain.intact, 10);
  EXPECT_GE(plain.watch_hits, 1u) << "the probe must find the keyframe in plain traffic, or it proves nothing";
  const WireResult secure = SendKeyframes(true, 176);
  EXPECT_EQ(secure.received, 10);
  EXPECT_EQ(secure.intact, 10);
  EXPECT_GT(secure.datagrams, 10u);
  EXPECT_EQ(secure.watch_hits, 0u) << "keyframe bytes readable on the secure wire";
}

// Revocation (make-pki.sh --revoke): with the CA's CRL in the server's directory, agent 2's
// certificate no longer authenticates with the server; agent 1's still does.
TEST(SecureWire, RevokedCertificateNoLongerMatches) {
  const std::string pki = ::testing::TempDir() + "/secure_wire_revoked";
  std::filesystem::remove_all(pki);
  const std::string make = std::string(CCM_MAKE_PKI) + " " + pki + " --agents 1 2 > " + pki + ".log 2>&1 && " +
                           CCM_MAKE_PKI + " " + pki + " --revoke 2 >> " + pki + ".log 2>&1";
  ASSERT_EQ(std::system(make.c_str()), 0) << make;
  ASSERT_TRUE(std::filesystem::exists(pki + "/server/identity_crl.pem"));
  rt::SessionOptions options;
  options.qos_file = std::string(CCM_QOS_DIR) + "/default.xml";
  options.domain_id = 178;
  std::string error;
  options.security_dir = pki + "/server";
  auto server = rt::DdsSession::Create(options, &error);
  ASSERT_TRUE(server) << error;
  auto reader = rt::TypedReader<msg::AgentStatusPubSubType>::Create(
      *server, rt::kTopicAgentStatus, rt::kProfileStatusReader, {64, rt::OverflowPolicy::kDropOldest}, &error,
      rt::kAllAgentsPartition);
  ASSERT_TRUE(reader) << error;
  // A robot given the new CRL refuses its own revoked certificate; the threat is a revoked
  // robot (or a thief) that kept the old files: without the CRL it starts, the server refuses it.
  options.security_dir = pki + "/agent_2";
  EXPECT_FALSE(rt::DdsSession::Create(options, &error));
  std::filesystem::remove(pki + "/agent_2/identity_crl.pem");
  std::vector<std::unique_ptr<rt::DdsSession>> agents;
  std::vector<std::unique_ptr<rt::TypedWriter<msg::AgentStatusPubSubType>>> writers;
  for (int id : {2, 1}) {
    options.security_dir = pki + "/agent_" + std::to_string(id);
    agents.push_back(rt::DdsSession::Create(options, &error));
    ASSERT_TRUE(agents.back()) << error;
    writers.push_back(rt::TypedWriter<msg::AgentStatusPubSubType>::Create(
        *agents.back(), rt::kTopicAgentStatus, rt::kProfileStatusWriter, &error, rt::AgentPartition(id)));
    ASSERT_TRUE(writers.back()) << error;
  }
  EXPECT_TRUE(writers[1]->WaitForMatch(1, std::chrono::seconds(20))) << "agent 1 (not revoked) must match";
  // Both started together: by the time agent 1 matched, agent 2's handshake was refused.
  std::this_thread::sleep_for(std::chrono::seconds(2));
  EXPECT_EQ(writers[0]->matched(), 0) << "the revoked agent 2 matched the server";
  EXPECT_EQ(reader->matched(), 1);
}

TEST(SecureWire, MissingSecurityFileIsAClearError) {
  const std::string dir = ::testing::TempDir() + "/secure_wire_incomplete";
  std::filesystem::remove_all(dir);
  std::filesystem::copy(Pki() + "/agent_1", dir);
  std::filesystem::remove(dir + "/permissions.p7s");
  rt::SessionOptions options;
  options.qos_file = std::string(CCM_QOS_DIR) + "/default.xml";
  options.domain_id = 177;
  options.security_dir = dir;
  std::string error;
  EXPECT_FALSE(rt::DdsSession::Create(options, &error));
  EXPECT_NE(error.find("permissions.p7s"), std::string::npos) << error;
}

// A transport with wifi.xml's 1400 B datagrams cannot carry the handshake: refused up front,
// not a silent no-match. (One QoS file per process, so the descriptor is built here.)
TEST(SecureWire, TooSmallDatagramsAreAClearError) {
  rt::SessionOptions options;
  options.security_dir = Pki() + "/agent_1";
  eprosima::fastdds::dds::DomainParticipantQos qos;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->maxMessageSize = 1400;
  qos.transport().user_transports.push_back(udp);
  qos.transport().use_builtin_transports = false;
  std::string error;
  EXPECT_FALSE(rt::ApplySecurity(options, &qos, &error));
  EXPECT_NE(error.find("maxMessageSize 1400"), std::string::npos) << error;
  udp->maxMessageSize = 65500;
  EXPECT_TRUE(rt::ApplySecurity(options, &qos, &error)) << error;
  std::set<std::string> names;
  for (const auto& p : qos.properties().properties()) {
    EXPECT_TRUE(names.insert(p.name()).second) << "property twice: " << p.name();
  }
  for (const char* name : {"dds.sec.auth.plugin", "dds.sec.access.plugin", "dds.sec.crypto.plugin",
                           "dds.sec.auth.builtin.PKI-DH.private_key",
                           "dds.sec.access.builtin.Access-Permissions.permissions"}) {
    EXPECT_EQ(names.count(name), 1u) << name;
  }
}

TEST(SecureWire, AgentIdOfPartition) {
  EXPECT_EQ(rt::AgentIdOfPartition("agent_1"), 1);
  EXPECT_EQ(rt::AgentIdOfPartition(rt::AgentPartition(65535)), 65535);
  EXPECT_EQ(rt::AgentIdOfPartition("agent_0"), -1);
  EXPECT_EQ(rt::AgentIdOfPartition("agent_01"), -1);  // one spelling per agent
  EXPECT_EQ(rt::AgentIdOfPartition("agent_10"), 10);
  EXPECT_EQ(rt::AgentIdOfPartition("agent_65536"), -1);
  EXPECT_EQ(rt::AgentIdOfPartition("agent_*"), -1);
  EXPECT_EQ(rt::AgentIdOfPartition("agent_1x"), -1);
  EXPECT_EQ(rt::AgentIdOfPartition(""), -1);
  EXPECT_EQ(rt::AgentIdOfParticipantName("ccm_agent_3"), 3);
  EXPECT_EQ(rt::AgentIdOfParticipantName("ccm_server"), -1);
  EXPECT_EQ(rt::AgentIdOfParticipantName("ccm_agent_"), -1);
  EXPECT_EQ(rt::AgentIdOfParticipantName("xccm_agent_3"), -1);
  EXPECT_EQ(rt::AgentIdOfParticipantName("cc"), -1);
}

}  // namespace
}  // namespace ccm
