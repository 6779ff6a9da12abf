// ccm_flooder: one hostile (or broken) agent that floods the server, for the flood test
// (flood_test.cpp, issue 28). As agent --id, in its own partition, it sends heartbeats and,
// at --rate keyframes per second, full-size synthetic keyframes (1000 keypoints, ~40 kB) with
// their points, each keyframe in a fresh map segment when --fresh-segments is set (every
// new (agent, segment) would be a new server map without the per-agent segment budget).
// Writes that the reliable writer refused (history full) are counted, not retried: a
// flooder does not care. Prints one JSON object when --duration is over, with the process's
// memory at 60 % of the flood and at the end: the writers' DDS histories are bounded
// by the QoS profile, so a flood (or a long flight) must not grow it. --mixed-sizes sends
// what a real flight sends: every other keyframe anchor-sized (no keypoints), full ones of
// 500-2000 keypoints and point batches of 0-300 points, so the history's slots see samples
// of different sizes (a history pool that keeps each slot at its largest sample grows then).
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <iostream>
#include <thread>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/process_memory.h"
#include "runtime_common/synthetic_msgs.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"
#include "slam_core/common/ids.h"

namespace rt = ccm::rt;
namespace msg = ccm::msg;

namespace {

constexpr int kFeatures = 1000;
constexpr int kPointsPerKeyframe = 100;

// The points keyframe `index` links to (synthetic::MakeKeyframe's own_mp_base + offsets),
// observed by that keyframe only, in its segment.
msg::MapPointBatch PointsOf(uint16_t agent, uint64_t index, const msg::KeyframeFull& kf, int num_points) {
  msg::MapPointBatch batch;
  batch.protocol_version(msg::kProtocolVersion);
  batch.agent_id(agent);
  batch.segment_counter(static_cast<uint32_t>(ccm::MapId(kf.segment_id()).counter()));
  for (int i = 0; i < num_points; ++i) {
    msg::MapPointFull p = ccm::synthetic::MakeMapPoint(agent, index * 1000 + static_cast<uint64_t>(i), 0);
    p.ref_kf_id(kf.id());
    p.obs_kf_offsets().push_back(0);
    p.obs_keypoint_index().push_back(static_cast<uint16_t>(i));
    batch.points().push_back(std::move(p));
  }
  return batch;
}

// Deterministic sizes spread over [0, n) for --mixed-sizes (Knuth's multiplicative hash).
int Spread(uint64_t index, int n) { return static_cast<int>((index * 2654435761ULL >> 7) % static_cast<uint64_t>(n)); }

}  // namespace

int main(int argc, char** argv) {
  rt::SessionOptions options;
  int id = 9;
  double rate = 26.0, duration_s = 20.0;
  bool fresh_segments = false, wait_match = false, mixed_sizes = false;
  CLI::App app{"ccm_flooder: one agent flooding the server with keyframes (flood test)"};
  app.add_option("--domain", options.domain_id, "DDS domain id");
  app.add_option("--qos", options.qos_file, "QoS profiles file");
  app.add_option("--id", id, "agent id to flood as")->check(CLI::Range(1, 65535))->capture_default_str();
  app.add_option("--rate", rate, "keyframes per second")->check(CLI::Range(0.1, 1000.0))->capture_default_str();
  app.add_option("--duration", duration_s, "seconds")->capture_default_str();
  app.add_flag("--fresh-segments", fresh_segments, "every keyframe in a new map segment");
  app.add_flag("--mixed-sizes", mixed_sizes, "keyframes and point batches of a real flight's different sizes");
  app.add_flag("--wait-match", wait_match, "start writing once the server's readers matched (up to 10 s)");
  CLI11_PARSE(app, argc, argv);
  options.participant_name = "ccm_flooder";

  nlohmann::json out;
  std::string error;
  auto session = rt::DdsSession::Create(options, &error);
  const std::string partition = rt::AgentPartition(id);
  auto kf_writer = session ? rt::TypedWriter<msg::KeyframeFullPubSubType>::Create(
                                 *session, rt::kTopicKeyframes, rt::kProfileNewDataWriter, &error, partition)
                           : nullptr;
  auto point_writer = session ? rt::TypedWriter<msg::MapPointBatchPubSubType>::Create(
                                    *session, rt::kTopicMapPoints, rt::kProfileNewDataWriter, &error, partition)
                              : nullptr;
  auto status_writer = session ? rt::TypedWriter<msg::AgentStatusPubSubType>::Create(
                                     *session, rt::kTopicAgentStatus, rt::kProfileStatusWriter, &error, partition)
                               : nullptr;
  if (!kf_writer || !point_writer || !status_writer) {
    std::cerr << "ccm_flooder: " << error << "\n";
    return 1;
  }
  const auto agent = static_cast<uint16_t>(id);
  if (wait_match) {
    kf_writer->WaitForMatch(1, std::chrono::seconds(10));
    point_writer->WaitForMatch(1, std::chrono::seconds(10));
  }
  const auto start = std::chrono::steady_clock::now();
  const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(1.0 / rate));
  const auto end = start + std::chrono::duration<double>(duration_s);
  int64_t written = 0, refused = 0;
  auto next_status = start;
  const auto midway = start + std::chrono::duration<double>(duration_s * 0.6);
  double rss_midway_mb = 0.0;
  uint64_t index = 0;
  for (auto next = start; std::chrono::steady_clock::now() < end; next += period) {
    std::this_thread::sleep_until(next);
    const auto now = std::chrono::steady_clock::now();
    if (now >= next_status) {
      status_writer->Write(ccm::synthetic::MakeAgentStatus(agent, index));
      next_status = now + std::chrono::milliseconds(500);
    }
    const bool anchor = mixed_sizes && index % 2 == 1;
    const int features = anchor ? 0 : mixed_sizes ? 500 + Spread(index, 1500) : kFeatures;
    const int num_points = anchor ? 0 : mixed_sizes ? Spread(index + 17, 300) : kPointsPerKeyframe;
    msg::KeyframeFull kf = ccm::synthetic::MakeKeyframe(agent, index, features, std::min(num_points, features));
    kf.anchor_only(anchor);
    if (fresh_segments) {
      // A new segment starts without a predecessor, like an agent's first keyframe after a reset.
      kf.segment_id(ccm::MapId::Make(agent, index + 1).packed());
      kf.predecessor_id(0);
      kf.parent_id(0);
    }
    const msg::MapPointBatch points = PointsOf(agent, index, kf, std::min(num_points, features));
    (kf_writer->Write(kf) ? written : refused) += 1;
    (point_writer->Write(points) ? written : refused) += 1;
    ++index;
    // Memory at 60 % of the flood (past 600 keyframes at 35/s): the writers' histories
    // (600 samples in the shipped profiles) are full, so it must not grow from here on.
    if (std::chrono::steady_clock::now() >= midway && rss_midway_mb == 0.0) rss_midway_mb = rt::CurrentRssMb();
  }
  out["agent"] = id;
  out["keyframes"] = index;
  out["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out["writes"] = written;
  out["writes_refused"] = refused;
  out["peak_rss_mb"] = rt::PeakRssMb();
  out["rss_midway_mb"] = rss_midway_mb;
  out["rss_at_end_mb"] = rt::CurrentRssMb();
  std::cout << out.dump() << std::endl;
  return 0;
}
