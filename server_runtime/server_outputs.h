// What ccm_server leaves behind when it stops with --out DIR, for every map that remains (an
// agent that never fused has a map of its own): map<k>_agent<id>_keyframes.tum per map and
// agent, agent<id>_keyframes.tum for the largest map, summary.json (every map with its agents,
// fusion and loop events with times, place recognition's counts, keyframe counts, timings;
// written by the replay tool's report code so offline and live runs read the same), map.ply
// (largest) and map<k>.ply, map_top.png (a panel per map), and server.json (the communication
// module's per-agent link counters and topic traffic). While it runs, main.cc appends
// timeline.jsonl there (mission_timeline.h).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "server_runtime/server_comm.h"
#include "slam_core/server/server_backend.h"

namespace ccm::server {

bool WriteServerOutputs(const std::string& dir, const ServerBackend& backend, const ServerCommStats& comm,
                        const std::vector<rt::TopicCountersSnapshot>& traffic, double wall_s, std::string* error);

/// The one-line JSON the server prints on exit (also the body of server.json).
std::string CommSummaryJson(const ServerCommStats& comm, const std::vector<rt::TopicCountersSnapshot>& traffic,
                            const BackendStats& backend, int indent = -1);

/// What ccm_server adds to the map view's status (map_view_server.h): each agent's link
/// (alive, tracking state from its heartbeat, keyframes sent/acknowledged) and DDS traffic.
nlohmann::json MapViewHostStatus(const ServerCommStats& comm, const std::vector<rt::TopicCountersSnapshot>& traffic);

}  // namespace ccm::server
