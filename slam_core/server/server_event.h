// What the back-end tells a user about in logs and summaries (new maps, fusions, loops,
// global BAs). Kept by the back-end's event sink, saved with the map stack.
#pragma once

#include <cstdint>
#include <string>

#include "slam_core/common/ids.h"
#include "slam_core/geometry/sim3.h"

namespace ccm {

/// Something a user wants to see in a log or a summary.
struct ServerEvent {
  enum class Kind { kNewMap, kFusion, kLoop, kGlobalBa };
  Kind kind = Kind::kNewMap;
  double time_s = 0.0;       ///< seconds since the back-end started (wall clock)
  int64_t stamp_ns = 0;      ///< data time: the stamp of the keyframe that caused it
  AgentId agent = 0;         ///< whose keyframe caused it
  MapId map, other_map;      ///< fusion: kept, absorbed
  KeyframeId query, candidate;
  /// Loop / fusion: the verified camera-frame similarity p_query = S * p_candidate (what an
  /// evaluation compares with ground truth).
  Sim3 query_from_candidate;
  int keyframes = 0;         ///< size of the map afterwards
  double seconds = 0.0;      ///< how long the step took
  std::string detail;
};

inline const char* ServerEventKindName(ServerEvent::Kind kind) {
  switch (kind) {
    case ServerEvent::Kind::kNewMap: return "new_map";
    case ServerEvent::Kind::kFusion: return "fusion";
    case ServerEvent::Kind::kLoop: return "loop";
    case ServerEvent::Kind::kGlobalBa: return "global_ba";
  }
  return "?";
}

}  // namespace ccm
