// ccm_intruder: a participant that is not (or not only) who it claims to be, for the secure
// link test (secure_link_test.cpp, docs/security.md). It tries, for --duration seconds, to
//  * inject: keyframes and heartbeats claiming agent --claim (a robot of the team) and
//    --fake (a robot that does not exist), written in the claimed agent's partition and,
//    if --own differs, in its own agent's partition;
//  * eavesdrop: every agent's keyframes (partition agent_*) and the server's messages to
//    the claimed agent.
// With --own it also sends honest heartbeats as agent --own (so a test can see that this
// participant does reach the server when its permissions allow). Endpoints that its own
// access control refuses are counted, not fatal. Prints one JSON object.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <iostream>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/synthetic_msgs.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"

namespace rt = ccm::rt;
namespace msg = ccm::msg;

int main(int argc, char** argv) {
  rt::SessionOptions options;
  int claim = 1, fake = 7, own = 0;
  double duration_s = 8.0;
  CLI::App app{"ccm_intruder: tries to inject into and read from a team's link (secure link test)"};
  app.add_option("--domain", options.domain_id, "DDS domain id");
  app.add_option("--qos", options.qos_file, "QoS profiles file");
  app.add_option("--security-dir", options.security_dir, "DDS-Security files to use (none: no security)");
  app.add_option("--claim", claim, "agent id to impersonate")->capture_default_str();
  app.add_option("--fake", fake, "agent id of no robot, also claimed")->capture_default_str();
  app.add_option("--own", own, "agent id its certificate belongs to (0: none)")->capture_default_str();
  app.add_option("--duration", duration_s, "seconds")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  options.participant_name = "ccm_intruder";

  nlohmann::json out;
  std::string error;
  auto session = rt::DdsSession::Create(options, &error);
  out["participant"] = session != nullptr;
  if (!session) {
    out["error"] = error;
    std::cout << out.dump() << std::endl;
    return 0;
  }
  using KfWriter = rt::TypedWriter<msg::KeyframeFullPubSubType>;
  using StatusWriter = rt::TypedWriter<msg::AgentStatusPubSubType>;
  std::vector<std::unique_ptr<KfWriter>> kf_writers;
  std::vector<std::unique_ptr<StatusWriter>> status_writers;
  int refused = 0;
  std::vector<int> partitions = {claim};
  if (own != 0 && own != claim) partitions.push_back(own);
  for (int p : partitions) {
    auto kw = KfWriter::Create(*session, rt::kTopicKeyframes, rt::kProfileNewDataWriter, &error, rt::AgentPartition(p));
    kw ? kf_writers.push_back(std::move(kw)) : void(++refused);
    auto sw = StatusWriter::Create(*session, rt::kTopicAgentStatus, rt::kProfileStatusWriter, &error,
                                   rt::AgentPartition(p));
    sw ? status_writers.push_back(std::move(sw)) : void(++refused);
  }
  auto kf_reader = rt::TypedReader<msg::KeyframeFullPubSubType>::Create(
      *session, rt::kTopicKeyframes, rt::kProfileNewDataReader, {4096, rt::OverflowPolicy::kDropOldest}, &error,
      rt::kAllAgentsPartition);
  refused += kf_reader ? 0 : 1;
  auto server_reader = rt::TypedReader<msg::ServerToAgentPubSubType>::Create(
      *session, rt::kTopicServerToAgent, rt::kProfileServerReader, {64, rt::OverflowPolicy::kDropOldest}, &error,
      rt::AgentPartition(claim));
  refused += server_reader ? 0 : 1;

  // Forged keyframes (this or another intruder's) have stream indices from kForgedBase on;
  // anything else read on ccm/keyframes is the team's.
  constexpr uint64_t kForgedBase = 900000;
  auto forged = [&](const msg::KeyframeFull& kf) {
    const uint64_t counter = ccm::synthetic::KeyframeCounter(kf);
    return counter >= kForgedBase && counter < 2 * kForgedBase;
  };
  int written = 0, server_matched = 0, team_keyframes_read = 0, forged_keyframes_read = 0, server_msgs_read = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(duration_s);
  for (uint64_t i = 0; std::chrono::steady_clock::now() < end; ++i) {
    for (const int id : {claim, fake}) {
      // Ids far above what a real agent of this test uses (its life-based counters).
      msg::KeyframeFull kf = ccm::synthetic::MakeKeyframe(static_cast<uint16_t>(id), kForgedBase + i, 300, 50);
      for (auto& w : kf_writers) written += w->Write(kf) ? 1 : 0;
      for (auto& w : status_writers) w->Write(ccm::synthetic::MakeAgentStatus(static_cast<uint16_t>(id), i));
    }
    if (own != 0) {
      for (auto& w : status_writers) w->Write(ccm::synthetic::MakeAgentStatus(static_cast<uint16_t>(own), i));
    }
    if (kf_reader) {
      while (auto kf = kf_reader->Pop(std::chrono::milliseconds(0))) ++(forged(*kf) ? forged_keyframes_read : team_keyframes_read);
    }
    if (server_reader) {
      // Only the team's server writes this topic: a match means it got past authentication.
      server_matched = std::max(server_matched, server_reader->matched());
      while (server_reader->Pop(std::chrono::milliseconds(0))) ++server_msgs_read;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  out["endpoints_refused_locally"] = refused;
  out["writers"] = kf_writers.size() + status_writers.size();
  out["keyframes_written"] = written;
  out["server_writer_matched"] = server_reader ? server_matched : -1;
  out["team_keyframes_read"] = team_keyframes_read;
  out["forged_keyframes_read"] = forged_keyframes_read;
  out["server_msgs_read"] = server_msgs_read;
  std::cout << out.dump() << std::endl;
  return 0;
}
