// The map view's JSON API (issue 14), as pure functions of a snapshot: no socket, no lock,
// so the HTTP server's handlers stay trivial and the tests call these directly.
//   GET /api/status                      team status, totals, queues, host facts, timing
//   GET /api/map?since=N&min_weight=W    keyframes, points, covisibility edges changed since
//                                        version N (0: everything), and what was removed
//   GET /api/events?since=K&limit=L      fusion, loop, new-map and global-BA events from index K
// Ids are "agent:counter" strings; poses world_from_cam as [x, y, z, qx, qy, qz, qw] in the
// keyframe's server map. Bad requests get a 4xx with {"error": "..."}; docs/map-view.md.
#pragma once

#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "server_runtime/map_view_snapshot.h"

namespace ccm::server {

struct ApiResponse {
  int status = 200;
  std::string body;
  std::string content_type = "application/json";
};

/// Query parameters, each name once (a repeated name is a bad request: see ParseQuery).
using QueryParams = std::map<std::string, std::string>;

/// Answers one GET under /api/. `extra_status` is merged into /api/status (the HTTP
/// server's own counters).
ApiResponse HandleApiRequest(const MapViewSnapshot& snapshot, const std::string& path, const QueryParams& params,
                             const nlohmann::json& extra_status = nlohmann::json::object());

/// A 4xx/5xx answer with {"error": message, "status": code}.
ApiResponse ApiError(int status, const std::string& message);

}  // namespace ccm::server
