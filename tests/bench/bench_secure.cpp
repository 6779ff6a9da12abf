// bench_secure: what the secure profile costs (docs/security.md). Two participants in one
// process (an agent writing keyframes in its partition, the server reading), over UDP
// loopback, once without and once with DDS-Security (certificates from --pki, made by
// deploy/security/make-pki.sh). Prints, per mode: time to match (discovery + handshake),
// bytes and datagrams on the wire for a burst of keyframes and per small keyframe update,
// and the one-way latency of keyframes written one at a time. No pass/fail.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/synthetic_msgs.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"

namespace {

using Clock = std::chrono::steady_clock;
namespace rt = ccm::rt;
namespace msg = ccm::msg;

struct Numbers {
  double match_s = 0, burst_s = 0, wire_mb = 0, payload_mb = 0;
  std::uint64_t datagrams = 0;
  double small_wire_b = 0, small_payload_b = 0;  ///< per keyframe update (148 B), one per datagram
  std::vector<double> latency_ms;
};

Numbers Run(const std::string& qos, const std::string& pki, int domain, int burst, int features, int pings) {
  rt::SessionOptions options;
  options.qos_file = qos;
  options.domain_id = domain;
  options.count_wire = true;
  rt::SessionOptions server_options = options;
  if (!pki.empty()) {
    options.security_dir = pki + "/agent_1";
    server_options.security_dir = pki + "/server";
  }
  std::string error;
  const auto start = Clock::now();
  auto server = rt::DdsSession::Create(server_options, &error);
  auto agent = server ? rt::DdsSession::Create(options, &error) : nullptr;
  if (!agent) throw std::runtime_error(error);
  auto reader = rt::TypedReader<msg::KeyframeFullPubSubType>::Create(
      *server, rt::kTopicKeyframes, rt::kProfileNewDataReader, {100000, rt::OverflowPolicy::kDropOldest}, &error,
      rt::kAllAgentsPartition);
  auto writer = rt::TypedWriter<msg::KeyframeFullPubSubType>::Create(
      *agent, rt::kTopicKeyframes, rt::kProfileNewDataWriter, &error, rt::AgentPartition(1));
  if (!reader || !writer) throw std::runtime_error(error);
  if (!writer->WaitForMatch(1, std::chrono::seconds(30))) throw std::runtime_error("no match");
  Numbers n;
  n.match_s = std::chrono::duration<double>(Clock::now() - start).count();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let discovery traffic settle

  std::vector<msg::KeyframeFull> kfs;
  for (int i = 0; i < burst; ++i) kfs.push_back(ccm::synthetic::MakeKeyframe(1, i, features, 300));
  const auto bytes0 = server->fault_counters().bytes_received.load();
  const auto datagrams0 = server->fault_counters().datagrams_received.load();
  const auto t0 = Clock::now();
  for (const auto& kf : kfs) writer->Write(kf);
  for (int got = 0; got < burst && reader->Pop(std::chrono::seconds(5)); ++got) {
  }
  n.burst_s = std::chrono::duration<double>(Clock::now() - t0).count();
  n.wire_mb = (server->fault_counters().bytes_received.load() - bytes0) / 1e6;
  n.datagrams = server->fault_counters().datagrams_received.load() - datagrams0;
  for (const auto& t : agent->TrafficSnapshot()) n.payload_mb += t.payload_bytes / 1e6;

  // Small samples: keyframe updates written one at a time, so each travels alone (the
  // per-sample cost of the secure submessage and payload wrapping shows in full).
  {
    auto up_reader = rt::TypedReader<msg::KeyframeUpdatePubSubType>::Create(
        *server, rt::kTopicKeyframeUpdates, rt::kProfileUpdateReader, {100000, rt::OverflowPolicy::kDropOldest},
        &error, rt::kAllAgentsPartition);
    auto up_writer = rt::TypedWriter<msg::KeyframeUpdatePubSubType>::Create(
        *agent, rt::kTopicKeyframeUpdates, rt::kProfileUpdateWriter, &error, rt::AgentPartition(1));
    if (!up_reader || !up_writer || !up_writer->WaitForMatch(1, std::chrono::seconds(30))) {
      throw std::runtime_error("no match on updates: " + error);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    constexpr int kUpdates = 200;
    const auto b0 = server->fault_counters().bytes_received.load();
    int got = 0;
    for (int i = 0; i < kUpdates; ++i) {
      up_writer->Write(ccm::synthetic::MakeKeyframeUpdate(1, i));
      if (up_reader->Pop(std::chrono::milliseconds(200))) ++got;
    }
    n.small_wire_b = double(server->fault_counters().bytes_received.load() - b0) / std::max(1, got);
    n.small_payload_b = double(up_writer->counters().payload_bytes) / kUpdates;
  }

  for (int i = 0; i < pings; ++i) {
    const msg::KeyframeFull kf = ccm::synthetic::MakeKeyframe(1, burst + i, features, 300);
    const auto sent = Clock::now();
    writer->Write(kf);
    if (reader->Pop(std::chrono::seconds(5))) {
      n.latency_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - sent).count());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::sort(n.latency_ms.begin(), n.latency_ms.end());
  return n;
}

double Percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  return sorted[std::min(sorted.size() - 1, static_cast<size_t>(p * (sorted.size() - 1) + 0.5))];
}

}  // namespace

int main(int argc, char** argv) {
  std::string pki;
  std::string qos = std::string(CCM_QOS_DIR) + "/default.xml";
  int burst = 40, features = 1000, pings = 60;
  CLI::App app{"bench_secure: traffic and latency of the secure profile against the plain one"};
  app.add_option("--pki", pki, "directory made by deploy/security/make-pki.sh DIR --agents 1")->required();
  app.add_option("--qos", qos, "QoS profiles file")->capture_default_str();
  app.add_option("--keyframes", burst, "keyframes in the burst")->capture_default_str();
  app.add_option("--features", features, "keypoints per keyframe")->capture_default_str();
  app.add_option("--pings", pings, "keyframes sent one at a time (latency)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    const Numbers plain = Run(qos, "", 191, burst, features, pings);
    const Numbers secure = Run(qos, pki, 192, burst, features, pings);
    std::printf("%-8s %9s %10s %10s %10s %10s %12s %12s %12s\n", "mode", "match s", "payload MB", "wire MB",
                "datagrams", "burst s", "lat p50 ms", "lat p95 ms", "lat max ms");
    for (const auto& [name, n] : {std::pair<const char*, const Numbers&>{"plain", plain}, {"secure", secure}}) {
      std::printf("%-8s %9.2f %10.3f %10.3f %10llu %10.3f %12.2f %12.2f %12.2f\n", name, n.match_s, n.payload_mb,
                  n.wire_mb, static_cast<unsigned long long>(n.datagrams), n.burst_s, Percentile(n.latency_ms, 0.5),
                  Percentile(n.latency_ms, 0.95), n.latency_ms.empty() ? 0.0 : n.latency_ms.back());
    }
    for (const auto& [name, n] : {std::pair<const char*, const Numbers&>{"plain", plain}, {"secure", secure}}) {
      std::printf("%-8s keyframe update: %.0f B payload, %.0f B on the wire per sample (incl. heartbeats)\n", name,
                  n.small_payload_b, n.small_wire_b);
    }
    std::printf("secure/plain: keyframe burst wire bytes x%.3f, update wire bytes x%.2f, p50 latency %+.2f ms\n",
                secure.wire_mb / plain.wire_mb, secure.small_wire_b / plain.small_wire_b,
                Percentile(secure.latency_ms, 0.5) - Percentile(plain.latency_ms, 0.5));
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
