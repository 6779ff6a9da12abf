#include "server_runtime/server_outputs.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "runtime_common/process_memory.h"
#include "server_runtime/run_report.h"

namespace ccm::server {

namespace {

nlohmann::json FusionStages(const PlaceMatcherStats& place) {
  nlohmann::json j = nlohmann::json::object();
  for (int s = 0; s < kNumVerificationStages; ++s) {
    j[VerificationStageName(static_cast<VerificationStage>(s))] = place.fusion_stopped_at[s];
  }
  return j;
}

}  // namespace

std::string CommSummaryJson(const ServerCommStats& comm, const std::vector<rt::TopicCountersSnapshot>& traffic,
                            const BackendStats& backend, int indent) {
  nlohmann::json agents = nlohmann::json::object();
  for (const auto& [id, l] : comm.agents) {
    const AgentCounters counters = backend.agents.count(id) ? backend.agents.at(id) : AgentCounters{};
    agents[std::to_string(id)] = {{"keyframes_received", l.keyframes},
                                  {"map_points_received", l.map_points},
                                  {"keyframe_updates_received", l.keyframe_updates},
                                  {"map_point_updates_received", l.map_point_updates},
                                  {"keyframes_registered", counters.keyframes_registered},
                                  {"keyframes_skipped_as_duplicates", counters.keyframes_duplicate},
                                  {"keyframes_received_as_anchors", counters.keyframes_anchor_only},
                                  {"keyframes_kept_on_track", counters.keyframes_kept_on_track},
                                  {"keyframes_deferred_for_points", counters.keyframes_deferred},
                                  {"refinements_refused", counters.refinements_refused},
                                  {"status_msgs", l.status_msgs},
                                  {"rejected", l.rejected},
                                  {"batches_submitted", l.batches_submitted},
                                  {"batches_dropped", l.batches_dropped},
                                  {"messages_sent", l.messages_sent},
                                  {"neighbourhoods_sent", l.neighbourhoods_sent},
                                  {"neighbourhoods_deferred", l.neighbourhoods_deferred},
                                  {"neighbourhood_keyframes_full", l.neighbourhood_keyframes_full},
                                  {"neighbourhood_keyframes_as_poses", l.neighbourhood_keyframes_as_poses},
                                  {"neighbourhood_points_full", l.neighbourhood_points_full},
                                  {"neighbourhood_points_as_positions", l.neighbourhood_points_as_positions},
                                  {"keyframes_released_incomplete", l.keyframes_released_incomplete},
                                  {"segments", l.segments.size()},
                                  {"leaves", l.leaves},
                                  {"agent_reported", {{"kfs_created", l.kfs_created},
                                                      {"kfs_sent", l.kfs_sent},
                                                      {"kfs_acked", l.kfs_acked},
                                                      {"kfs_resent", l.kfs_resent},
                                                      {"kfs_lost", l.kfs_lost}}}};
  }
  nlohmann::json topics = nlohmann::json::object();
  for (const auto& t : traffic) {
    topics[t.topic + ":" + t.direction] = {{"samples", t.samples},
                                           {"bytes", t.payload_bytes},
                                           {"write_failures", t.write_failures},
                                           {"samples_lost", t.samples_lost},
                                           {"queue_dropped", t.queue_dropped}};
  }
  const nlohmann::json j = {{"elapsed_s", comm.elapsed_s},
                            {"peak_rss_mb", rt::PeakRssMb()},
                            {"agents", agents},
                            {"refused_agents", comm.refused_agents},
                            {"released_agents", comm.released_agents},
                            {"rejected", comm.rejected},
                            {"rejected_by_kind", comm.rejected_by_kind},
                            {"wrong_partition", comm.wrong_partition},
                            {"fusions", backend.fusions},
                            {"loops", backend.loops},
                            // Why maps did or did not fuse: each stage's count, in order.
                            {"place_recognition", {{"queries", backend.place.queries},
                                                   {"fusion_candidates", backend.place.match_candidates},
                                                   {"loop_candidates", backend.place.loop_candidates},
                                                   {"verified", backend.place.verified},
                                                   {"inconsistent", backend.place.inconsistent},
                                                   {"implausible_loops", backend.place.implausible_loops},
                                                   {"accepted_fusions", backend.place.accepted_fusions},
                                                   {"accepted_loops", backend.place.accepted_loops},
                                                   {"fusion_verifications_stopped_at", FusionStages(backend.place)}}},
                            {"traffic", topics}};
  return j.dump(indent);
}

nlohmann::json MapViewHostStatus(const ServerCommStats& comm, const std::vector<rt::TopicCountersSnapshot>& traffic) {
  static const char* kTracking[] = {"initializing", "tracking", "lost"};
  nlohmann::json agents = nlohmann::json::object();
  for (const auto& [id, l] : comm.agents) {
    const bool known = l.tracking_state >= 0 && l.tracking_state <= 2;
    agents[std::to_string(id)] = {{"alive", l.alive},
                                  {"tracking", known ? kTracking[l.tracking_state] : "unknown"},
                                  {"last_seen_s", std::round(l.last_seen_s * 10.0) / 10.0},
                                  {"kfs_sent", l.kfs_sent},
                                  {"kfs_acked", l.kfs_acked},
                                  {"kfs_lost", l.kfs_lost},
                                  {"leaves", l.leaves},
                                  {"batches_dropped", l.batches_dropped}};
  }
  nlohmann::json topics = nlohmann::json::array();
  for (const auto& t : traffic) {
    topics.push_back({{"topic", t.topic}, {"direction", t.direction}, {"samples", t.samples},
                      {"bytes", t.payload_bytes}, {"lost", t.samples_lost}, {"queue_dropped", t.queue_dropped}});
  }
  return {{"source", "ccm_server"}, {"elapsed_s", std::round(comm.elapsed_s * 10.0) / 10.0}, {"agents", agents},
          {"traffic", topics}, {"rejected", comm.rejected}, {"refused_agents", comm.refused_agents}};
}

bool WriteServerOutputs(const std::string& dir, const ServerBackend& backend, const ServerCommStats& comm,
                        const std::vector<rt::TopicCountersSnapshot>& traffic, double wall_s, std::string* error) {
  // The live server has no ground truth: the report scores nothing and names the files.
  report::RunResult result;
  const BackendStatus status = backend.Status();
  const MapStackSnapshot maps = backend.Snapshot();
  for (const AgentId id : status.agents) {
    report::AgentRunResult a;
    a.name = "agent" + std::to_string(id);
    a.id = id;
    a.server_keyframes = maps.AgentTrajectory(id);
    if (comm.agents.count(id)) {
      a.keyframes_created = comm.agents.at(id).kfs_created;
      a.segments = static_cast<int>(comm.agents.at(id).segments.size());
    }
    result.agents.push_back(std::move(a));
  }
  result.events = maps.events;
  result.maps = maps.Summaries();
  result.stats = status.stats;
  result.wall_s = wall_s;
  const report::RunEvaluation ev = report::EvaluateRun(result);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    *error = "cannot create " + dir + ": " + ec.message();
    return false;
  }
  // Without any map (no agent ever sent a keyframe) there is nothing to draw.
  if (!result.maps.empty() && !report::WriteRunOutputs(dir, result, ev, maps, error)) return false;
  std::ofstream out(dir + "/server.json");
  out << CommSummaryJson(comm, traffic, result.stats, 2) << "\n";
  if (!out) {
    *error = "cannot write " + dir + "/server.json";
    return false;
  }
  return true;
}

}  // namespace ccm::server
