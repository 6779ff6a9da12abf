// ccm_link_probe: one end of a two-process link test. The publisher streams synthetic
// full keyframes (RELIABLE new-data profile) or keyframe updates (BEST_EFFORT update
// profile) at a fixed rate; the subscriber regenerates every expected message and checks
// that each arrived exactly once with identical content. Both print a one-line JSON summary
// (also written to --result) so tests and the demo can read the outcome.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <fstream>
#include <iostream>
#include <set>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "slam_core/common/ids.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"
#include "runtime_common/synthetic_msgs.h"

namespace {

using Clock = std::chrono::steady_clock;
using ccm::rt::DdsSession;

struct ProbeOptions {
  std::string role;
  std::string kind = "keyframes";  // keyframes | updates
  int count = 200;
  double rate_hz = 10.0;
  int features = 1000;
  int associations = 300;
  double timeout_s = 60.0;
  double idle_s = 3.0;
  std::uint16_t agent = 1;
  std::string result_path;
};

nlohmann::json FaultJson(const DdsSession& session) {
  const auto& f = session.fault_counters();
  return {{"datagrams_received", f.datagrams_received.load()}, {"datagrams_dropped", f.datagrams_dropped.load()},
          {"bytes_received", f.bytes_received.load()}};
}

nlohmann::json TrafficJson(const DdsSession& session) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& t : session.TrafficSnapshot()) {
    out.push_back({{"topic", t.topic}, {"direction", t.direction}, {"samples", t.samples},
                   {"payload_bytes", t.payload_bytes}, {"write_failures", t.write_failures},
                   {"samples_lost", t.samples_lost}, {"queue_dropped", t.queue_dropped}});
  }
  return out;
}

template <typename PubSubT, typename MakeFn>
nlohmann::json Publish(DdsSession& session, const ProbeOptions& o, const char* topic, const char* profile,
                       MakeFn make) {
  std::string error;
  auto writer = ccm::rt::TypedWriter<PubSubT>::Create(session, topic, profile, &error);
  if (!writer) throw std::runtime_error(error);
  if (!writer->WaitForMatch(1, std::chrono::seconds(static_cast<int>(o.timeout_s)))) {
    throw std::runtime_error("no subscriber matched within the timeout");
  }
  const auto period = std::chrono::duration<double>(1.0 / o.rate_hz);
  const auto start = Clock::now();
  int failures = 0;
  for (int i = 0; i < o.count; ++i) {
    std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(period * i));
    if (!writer->Write(make(i))) ++failures;
  }
  const double publish_s = std::chrono::duration<double>(Clock::now() - start).count();
  const bool all_acked = writer->WaitForAcknowledgments(std::chrono::seconds(static_cast<int>(o.timeout_s)));
  const double acked_s = std::chrono::duration<double>(Clock::now() - start).count();
  // Stay matched a little so best-effort stragglers and final ACKs can flow.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  return {{"role", "pub"}, {"published", o.count - failures}, {"write_failures", failures},
          {"publish_s", publish_s}, {"all_acked", all_acked}, {"acked_s", acked_s}};
}

template <typename PubSubT, typename MakeFn, typename IndexFn>
nlohmann::json Subscribe(DdsSession& session, const ProbeOptions& o, const char* topic, const char* profile,
                         ccm::rt::OverflowPolicy policy, MakeFn make, IndexFn index_of) {
  std::string error;
  auto reader = ccm::rt::TypedReader<PubSubT>::Create(session, topic, profile, {512, policy}, &error);
  if (!reader) throw std::runtime_error(error);
  std::set<long long> seen;  // ordered: *begin() is the first index that arrived
  int duplicates = 0, mismatches = 0, out_of_range = 0;
  const auto deadline = Clock::now() + std::chrono::duration<double>(o.timeout_s);
  auto last_data = Clock::now();
  bool got_any = false;
  while (static_cast<int>(seen.size()) < o.count && Clock::now() < deadline) {
    auto sample = reader->Pop(std::chrono::milliseconds(100));
    if (!sample) {
      if (got_any && Clock::now() - last_data > std::chrono::duration<double>(o.idle_s)) break;
      continue;
    }
    got_any = true;
    last_data = Clock::now();
    const long long index = index_of(*sample);
    if (index < 0 || index >= o.count) { ++out_of_range; continue; }
    if (!seen.insert(index).second) ++duplicates;
    if (!(*sample == make(static_cast<int>(index)))) ++mismatches;
  }
  std::vector<long long> missing;
  for (long long i = 0; i < o.count; ++i) if (!seen.count(i)) missing.push_back(i);
  return {{"role", "sub"}, {"expected", o.count}, {"received_unique", seen.size()}, {"duplicates", duplicates},
          {"mismatches", mismatches}, {"out_of_range", out_of_range}, {"missing_count", missing.size()},
          {"first_index", seen.empty() ? -1 : *seen.begin()},
          {"reader_samples_lost", reader->counters().samples_lost.load()}};
}

nlohmann::json Run(DdsSession& session, const ProbeOptions& o) {
  namespace rt = ccm::rt;
  using ccm::msg::KeyframeFullPubSubType;
  using ccm::msg::KeyframeUpdatePubSubType;
  auto make_kf = [&](int i) { return ccm::synthetic::MakeKeyframe(o.agent, i, o.features, o.associations); };
  auto make_update = [&](int i) { return ccm::synthetic::MakeKeyframeUpdate(o.agent, i); };
  const bool kfs = o.kind == "keyframes";
  if (o.role == "pub") {
    return kfs ? Publish<KeyframeFullPubSubType>(session, o, rt::kTopicKeyframes, rt::kProfileNewDataWriter, make_kf)
               : Publish<KeyframeUpdatePubSubType>(session, o, rt::kTopicKeyframeUpdates, rt::kProfileUpdateWriter,
                                                   make_update);
  }
  if (kfs) {
    return Subscribe<KeyframeFullPubSubType>(
        session, o, rt::kTopicKeyframes, rt::kProfileNewDataReader, rt::OverflowPolicy::kBlock, make_kf,
        [](const ccm::msg::KeyframeFull& kf) { return static_cast<long long>(ccm::synthetic::KeyframeCounter(kf)); });
  }
  return Subscribe<KeyframeUpdatePubSubType>(
      session, o, rt::kTopicKeyframeUpdates, rt::kProfileUpdateReader, rt::OverflowPolicy::kDropOldest, make_update,
      [](const ccm::msg::KeyframeUpdate& u) { return static_cast<long long>(ccm::KeyframeId(u.id()).counter()) - 1; });
}

}  // namespace

int main(int argc, char** argv) {
  ProbeOptions o;
  ccm::rt::SessionOptions session_options;
  CLI::App app{"ccm_link_probe: one end of a two-process DDS link test (publisher or subscriber)"};
  app.add_option("--role", o.role, "pub or sub")->required()->check(CLI::IsMember({"pub", "sub"}));
  app.add_option("--kind", o.kind, "keyframes (RELIABLE new data) or updates (BEST_EFFORT)")
      ->check(CLI::IsMember({"keyframes", "updates"}))->capture_default_str();
  app.add_option("--count", o.count, "messages to send / expect")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--rate", o.rate_hz, "publish rate [Hz]")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--features", o.features, "keypoints per keyframe")->check(CLI::Range(1, 4000))->capture_default_str();
  app.add_option("--timeout", o.timeout_s, "overall timeout [s]")->capture_default_str();
  app.add_option("--idle", o.idle_s, "subscriber stops after this long without data [s]")->capture_default_str();
  app.add_option("--domain", session_options.domain_id, "DDS domain id")->check(CLI::Range(0, 232))->capture_default_str();
  app.add_option("--qos", session_options.qos_file, "Fast DDS XML profiles file (default: $FASTRTPS_DEFAULT_PROFILES_FILE or qos_profiles/default.xml)");
  app.add_option("--drop", session_options.fault.drop_probability, "drop probability of received datagrams")->capture_default_str();
  app.add_option("--delay-ms", session_options.fault.delay_ms, "added delay of received datagrams [ms]")->capture_default_str();
  app.add_option("--result", o.result_path, "also write the JSON summary to this file");
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (session_options.fault.drop_probability == 0.0 && session_options.fault.delay_ms == 0.0) {
    auto from_env = ccm::rt::FaultOptions::FromEnvironment(&error);
    if (!from_env) { std::cerr << "error: " << error << "\n"; return 2; }
    session_options.fault = *from_env;
  }
  session_options.participant_name = "ccm_link_probe_" + o.role;
  auto session = DdsSession::Create(session_options, &error);
  if (!session) { std::cerr << "error: " << error << "\n"; return 2; }
  nlohmann::json result;
  try {
    result = Run(*session, o);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  result["kind"] = o.kind;
  result["fault"] = session_options.fault.ToString();
  result["wire"] = FaultJson(*session);
  result["traffic"] = TrafficJson(*session);
  std::cout << result.dump() << std::endl;
  if (!o.result_path.empty()) std::ofstream(o.result_path) << result.dump(2) << "\n";
  return 0;
}
