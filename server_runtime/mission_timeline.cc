#include "server_runtime/mission_timeline.h"

#include <algorithm>
#include <cmath>

#include "slam_core/eval/metrics.h"

namespace ccm::server {
namespace {

// To `unit` (0.1, 0.01, ...), dividing by its inverse so that 116.3 prints as 116.3.
double Round(double x, double unit) {
  const double per_unit = std::round(1.0 / unit);
  return std::round(x * per_unit) / per_unit;
}

}  // namespace

nlohmann::json MissionTimeline::Row(double elapsed_s, double rss_mb, const BackendStatus& status,
                                    const std::vector<MapSummary>& maps) {
  const BackendStats& stats = status.stats;
  // keyframe_ms keeps each agent's first 20,000 keyframes: beyond that a window sees none.
  std::vector<double> window_ms;
  for (const auto& [agent, counters] : stats.agents) {
    size_t& seen = keyframes_seen_[agent];
    for (size_t i = seen; i < counters.keyframe_ms.size(); ++i) window_ms.push_back(counters.keyframe_ms[i]);
    seen = std::max(seen, counters.keyframe_ms.size());
  }
  int window_bas = 0, ba_keyframes = 0;
  double ba_max_s = 0.0;
  for (size_t i = global_bas_seen_; i < stats.global_ba_seconds.size(); ++i) {
    ++window_bas;
    if (stats.global_ba_seconds[i].second >= ba_max_s) {
      ba_max_s = stats.global_ba_seconds[i].second;
      ba_keyframes = stats.global_ba_seconds[i].first;
    }
  }
  global_bas_seen_ = std::max(global_bas_seen_, stats.global_ba_seconds.size());
  size_t keyframes = 0, anchored = 0, points = 0;
  for (const MapSummary& m : maps) {
    keyframes += m.keyframes;
    anchored += m.anchored;
    points += m.map_points;
  }
  size_t deepest_queue = 0;
  for (const auto& [agent, depth] : status.queues.agent_batches) deepest_queue = std::max(deepest_queue, depth);
  return {{"t_s", Round(elapsed_s, 0.1)},
          {"rss_mb", Round(rss_mb, 0.1)},
          {"maps", maps.size()},
          {"keyframes", keyframes},
          {"anchored", anchored},
          {"map_points", points},
          {"keyframes_in_window", window_ms.size()},
          {"keyframe_ms_median", Round(Percentile(window_ms, 0.5), 0.01)},
          {"keyframe_ms_p95", Round(Percentile(window_ms, 0.95), 0.01)},
          {"global_bas_in_window", window_bas},
          {"global_ba_s_max", Round(ba_max_s, 0.001)},
          {"global_ba_keyframes", ba_keyframes},
          {"global_bas", stats.global_ba_applied},
          {"fusions", stats.fusions},
          {"loops", stats.loops},
          {"keyframes_removed", stats.keyframes_removed},
          {"deepest_queue", deepest_queue},
          {"place_recognition_queue", status.queues.place_recognition}};
}

bool MissionTimelineFile::Open(const std::string& path, std::string* error) {
  out_.open(path, std::ios::out | std::ios::trunc);
  if (!out_) {
    *error = "cannot write the mission timeline " + path;
    return false;
  }
  return true;
}

void MissionTimelineFile::Append(const nlohmann::json& row) {
  if (!out_.is_open()) return;
  out_ << row.dump() << '\n';
  out_.flush();
}

}  // namespace ccm::server
