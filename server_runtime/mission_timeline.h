// The server's course over a mission (issue 30, "long missions"): with --out DIR, ccm_server
// appends one JSON line per progress period to DIR/timeline.jsonl: memory, the maps' size,
// how long the keyframes of that period took (registration + server mapping), the global
// BAs applied in it and the deepest agent queue. A 30-minute flight then shows whether
// memory, per-keyframe work and BA time level off or keep growing
// (tests/fault_harness/long_flight.sh prints it).
#pragma once

#include <cstdint>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "slam_core/server/backend_status.h"
#include "slam_core/server/map_stack_snapshot.h"

namespace ccm::server {

class MissionTimeline {
 public:
  /// One row, from what the back-end reports; only keyframes and global BAs that are new
  /// since the previous row count in its window figures. Not thread-safe (the main thread).
  nlohmann::json Row(double elapsed_s, double rss_mb, const BackendStatus& status,
                     const std::vector<MapSummary>& maps);

 private:
  std::map<AgentId, size_t> keyframes_seen_;  ///< keyframe_ms entries already in a row
  size_t global_bas_seen_ = 0;
};

/// Appends rows to a file, one JSON object per line (flushed: a killed server keeps them).
class MissionTimelineFile {
 public:
  /// False (and `error`) if the file cannot be opened.
  bool Open(const std::string& path, std::string* error);
  void Append(const nlohmann::json& row);
  bool is_open() const { return out_.is_open(); }

 private:
  std::ofstream out_;
};

}  // namespace ccm::server
