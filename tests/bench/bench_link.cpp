// bench_link: bytes on the wire per topic and the bandwidth cap of the new-data profile.
// Two participants in one process exchange synthetic protocol messages over UDP loopback
// (intra-process delivery and data sharing are off in the profiles, so everything crosses
// the transport and its flow controller). Prints a table; no pass/fail.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"
#include "runtime_common/synthetic_msgs.h"

namespace {

using Clock = std::chrono::steady_clock;
namespace rt = ccm::rt;

template <typename PubSubT, typename MakeFn>
double Stream(rt::DdsSession& pub, rt::DdsSession& sub, const char* topic, const char* writer_profile,
              const char* reader_profile, int count, MakeFn make, int* received) {
  std::string error;
  auto reader = rt::TypedReader<PubSubT>::Create(sub, topic, reader_profile, {100000, rt::OverflowPolicy::kDropOldest}, &error);
  auto writer = rt::TypedWriter<PubSubT>::Create(pub, topic, writer_profile, &error);
  if (!reader || !writer) throw std::runtime_error(error);
  if (!writer->WaitForMatch(1, std::chrono::seconds(20)) || !reader->WaitForMatch(1, std::chrono::seconds(20))) {
    throw std::runtime_error(std::string("no match on ") + topic);
  }
  std::vector<typename PubSubT::type> msgs;
  for (int i = 0; i < count; ++i) msgs.push_back(make(i));
  const auto start = Clock::now();
  for (const auto& m : msgs) writer->Write(m);
  *received = 0;
  auto last = start;
  while (*received < count) {
    if (!reader->Pop(std::chrono::milliseconds(2000))) break;
    ++*received;
    last = Clock::now();
  }
  return std::chrono::duration<double>(last - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  int keyframes = 40;
  int features = 1000;
  std::string qos = std::string(CCM_QOS_DIR) + "/default.xml";
  CLI::App app{"bench_link: bytes on the wire per topic and the new-data bandwidth cap"};
  app.add_option("--keyframes", keyframes, "full keyframes to send in one burst")->capture_default_str();
  app.add_option("--features", features, "keypoints per keyframe")->capture_default_str();
  app.add_option("--qos", qos, "QoS profiles file")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  rt::SessionOptions options;
  options.qos_file = qos;
  options.domain_id = 190;
  options.count_wire = true;
  std::string error;
  auto pub = rt::DdsSession::Create(options, &error);
  auto sub = pub ? rt::DdsSession::Create(options, &error) : nullptr;
  if (!pub || !sub) {
    std::cerr << "error: " << error << "\n";
    return 1;
  }
  using namespace ccm;
  int got = 0;
  std::printf("%-24s %8s %10s %12s %10s %12s\n", "topic", "samples", "received", "payload B", "B/sample", "seconds");
  auto row = [&](const char* topic, int sent, int received, double seconds) {
    for (const auto& t : pub->TrafficSnapshot()) {
      if (t.topic != topic) continue;
      std::printf("%-24s %8d %10d %12llu %10.0f %12.3f\n", topic, sent, received,
                  static_cast<unsigned long long>(t.payload_bytes), double(t.payload_bytes) / std::max<std::uint64_t>(1, t.samples), seconds);
    }
  };
  const auto wire_before = sub->fault_counters().bytes_received.load();
  double s = Stream<msg::KeyframeFullPubSubType>(*pub, *sub, rt::kTopicKeyframes, rt::kProfileNewDataWriter,
                                                 rt::kProfileNewDataReader, keyframes,
                                                 [&](int i) { return synthetic::MakeKeyframe(1, i, features, 300); }, &got);
  row(rt::kTopicKeyframes, keyframes, got, s);
  const double kf_wire_mb = (sub->fault_counters().bytes_received.load() - wire_before) / 1e6;
  const double kf_payload_mb = pub->TrafficSnapshot().front().payload_bytes / 1e6;
  s = Stream<msg::MapPointFullPubSubType>(*pub, *sub, rt::kTopicMapPoints, rt::kProfileNewDataWriter,
                                          rt::kProfileNewDataReader, 2000,
                                          [](int i) { return synthetic::MakeMapPoint(1, i, 5); }, &got);
  row(rt::kTopicMapPoints, 2000, got, s);
  s = Stream<msg::KeyframeUpdatePubSubType>(*pub, *sub, rt::kTopicKeyframeUpdates, rt::kProfileUpdateWriter,
                                            rt::kProfileUpdateReader, 200,
                                            [](int i) { return synthetic::MakeKeyframeUpdate(1, i); }, &got);
  row(rt::kTopicKeyframeUpdates, 200, got, s);
  s = Stream<msg::MapPointUpdatePubSubType>(*pub, *sub, rt::kTopicMapPointUpdates, rt::kProfileUpdateWriter,
                                            rt::kProfileUpdateReader, 2000,
                                            [](int i) { return synthetic::MakeMapPointUpdate(1, i); }, &got);
  row(rt::kTopicMapPointUpdates, 2000, got, s);
  std::printf("\nkeyframe burst: %.2f MB payload, %.2f MB on the wire (UDP payload incl. RTPS headers)\n",
              kf_payload_mb, kf_wire_mb);
  std::printf("wire totals: %llu datagrams, %.2f MB received by the subscribing participant\n",
              static_cast<unsigned long long>(sub->fault_counters().datagrams_received.load()),
              sub->fault_counters().bytes_received.load() / 1e6);
  std::printf("cap check: %d keyframes = %.2f MB at the profile's cap take >= %.2f s at 2 MB/s\n", keyframes,
              kf_payload_mb, kf_payload_mb / 2.0);
  return 0;
}
