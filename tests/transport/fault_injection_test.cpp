// The fault-injection transport drops with the configured probability and delays by at
// least the configured time (in-process: two participants over UDP on loopback).
#include <gtest/gtest.h>

#include <cstdlib>
#include <set>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/typed_endpoints.h"
#include "runtime_common/synthetic_msgs.h"

namespace ccm {
namespace {

using Clock = std::chrono::steady_clock;

std::unique_ptr<rt::DdsSession> MakeSession(int domain, rt::FaultOptions fault, const std::string& name = "ccm",
                                            bool track_agents = false) {
  rt::SessionOptions options;
  options.qos_file = std::string(CCM_QOS_DIR) + "/default.xml";
  options.domain_id = domain;
  options.fault = fault;
  options.participant_name = name;
  options.track_agent_participants = track_agents;
  std::string error;
  auto session = rt::DdsSession::Create(options, &error);
  EXPECT_TRUE(session) << error;
  return session;
}

TEST(FaultOptions, ValidationAndEnvironment) {
  rt::FaultOptions o;
  EXPECT_TRUE(o.Validate().empty());
  EXPECT_FALSE(o.enabled());
  o.drop_probability = 1.0;
  EXPECT_FALSE(o.Validate().empty());
  o.drop_probability = -0.1;
  EXPECT_FALSE(o.Validate().empty());

  std::string error;
  setenv("CCM_FAULT_DROP", "0.25", 1);
  setenv("CCM_FAULT_DELAY_MS", "40", 1);
  auto env = rt::FaultOptions::FromEnvironment(&error);
  ASSERT_TRUE(env) << error;
  EXPECT_DOUBLE_EQ(env->drop_probability, 0.25);
  EXPECT_DOUBLE_EQ(env->delay_ms, 40.0);
  setenv("CCM_FAULT_DROP", "lots", 1);
  EXPECT_FALSE(rt::FaultOptions::FromEnvironment(&error));
  EXPECT_NE(error.find("CCM_FAULT_DROP"), std::string::npos);
  unsetenv("CCM_FAULT_DROP");
  unsetenv("CCM_FAULT_DELAY_MS");
}

TEST(FaultInjection, DropsTheConfiguredFractionOfDatagrams) {
  rt::FaultOptions fault;
  fault.drop_probability = 0.3;
  fault.seed = 7;
  auto sender = MakeSession(171, {});
  auto receiver = MakeSession(171, fault);
  ASSERT_TRUE(sender && receiver);
  std::string error;
  auto writer = rt::TypedWriter<msg::KeyframeUpdatePubSubType>::Create(*sender, "ccm/fault_test", "ccm_update_writer", &error);
  auto reader = rt::TypedReader<msg::KeyframeUpdatePubSubType>::Create(*receiver, "ccm/fault_test", "ccm_update_reader",
                                                                       {4096, rt::OverflowPolicy::kDropOldest}, &error);
  ASSERT_TRUE(writer && reader) << error;
  // Discovery itself runs through the lossy transport: allow time.
  ASSERT_TRUE(writer->WaitForMatch(1, std::chrono::seconds(20)));
  ASSERT_TRUE(reader->WaitForMatch(1, std::chrono::seconds(20)));
  const int kCount = 1500;
  for (int i = 0; i < kCount; ++i) {
    ASSERT_TRUE(writer->Write(synthetic::MakeKeyframeUpdate(1, i)));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  int received = 0;
  while (reader->Pop(std::chrono::milliseconds(1000))) ++received;
  const double rate = 1.0 - static_cast<double>(received) / kCount;
  EXPECT_NEAR(rate, 0.3, 0.06) << "received " << received << " of " << kCount;
  const auto& counters = receiver->fault_counters();
  const double measured = static_cast<double>(counters.datagrams_dropped) / counters.datagrams_received;
  EXPECT_NEAR(measured, 0.3, 0.05);
}

TEST(FaultInjection, DelaysEveryDeliveredDatagram) {
  rt::FaultOptions fault;
  fault.delay_ms = 100.0;
  auto sender = MakeSession(172, {});
  auto receiver = MakeSession(172, fault);
  ASSERT_TRUE(sender && receiver);
  std::string error;
  auto writer = rt::TypedWriter<msg::AgentStatusPubSubType>::Create(*sender, "ccm/delay_test", "ccm_status_writer", &error);
  auto reader = rt::TypedReader<msg::AgentStatusPubSubType>::Create(*receiver, "ccm/delay_test", "ccm_status_reader",
                                                                   {64, rt::OverflowPolicy::kDropOldest}, &error);
  ASSERT_TRUE(writer && reader) << error;
  ASSERT_TRUE(writer->WaitForMatch(1, std::chrono::seconds(20)));
  ASSERT_TRUE(reader->WaitForMatch(1, std::chrono::seconds(20)));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  int measured = 0;
  for (int i = 0; i < 10; ++i) {
    msg::AgentStatus status = synthetic::MakeAgentStatus(1, i);
    const auto sent = Clock::now();
    ASSERT_TRUE(writer->Write(status));
    auto got = reader->Pop(std::chrono::milliseconds(2000));
    if (!got) continue;
    const double latency_ms = std::chrono::duration<double, std::milli>(Clock::now() - sent).count();
    EXPECT_GE(latency_ms, 100.0);  // a lower bound: the delay can never be shorter
    ++measured;
  }
  EXPECT_GE(measured, 8);
}

// The server makes an agent's writers when discovery names "ccm_agent_<id>"; only a session
// created to track agents records them (others would fill a list nobody reads).
TEST(DdsSessionDiscovery, OnlyATrackingSessionRecordsAgentParticipants) {
  auto server = MakeSession(174, {}, "ccm_server", true);
  auto agent7 = MakeSession(174, {}, "ccm_agent_7");
  auto agent8 = MakeSession(174, {}, "ccm_agent_8");
  auto ctl = MakeSession(174, {}, "ccm_ctl");
  ASSERT_TRUE(server && agent7 && agent8 && ctl);
  std::set<int> seen;
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  while (seen.size() < 2 && Clock::now() < deadline) {
    for (const int id : server->TakeDiscoveredAgents()) seen.insert(id);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(seen, (std::set<int>{7, 8}));  // ccm_ctl and the server itself are no agents
  EXPECT_TRUE(server->TakeDiscoveredAgents().empty());  // taken once
  // agent7 discovered agent8 (and the others) by now, but does not track.
  EXPECT_TRUE(agent7->TakeDiscoveredAgents().empty());
  EXPECT_TRUE(ctl->TakeDiscoveredAgents().empty());
}

}  // namespace
}  // namespace ccm
