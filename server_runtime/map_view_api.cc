#include "server_runtime/map_view_api.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace ccm::server {
namespace {

constexpr int64_t kMaxWeight = 1000000;
constexpr int64_t kMaxEventsPerAnswer = 10000;

/// Parses a decimal integer in [lo, hi]; the message names the parameter and the range.
bool ParseInt(const QueryParams& params, const std::string& name, int64_t lo, int64_t hi, int64_t* value,
              std::string* error) {
  const auto it = params.find(name);
  if (it == params.end()) return true;  // keep the default
  const std::string& text = it->second;
  const bool digits = !text.empty() && text.size() <= 19 &&
                      text.find_first_not_of("0123456789") == std::string::npos;
  if (!digits) {
    *error = "parameter '" + name + "' must be a non-negative integer, got '" + text.substr(0, 40) + "'";
    return false;
  }
  const int64_t v = std::stoll(text);
  if (v < lo || v > hi) {
    *error = "parameter '" + name + "' = " + text + " is out of range " + std::to_string(lo) + ".." + std::to_string(hi);
    return false;
  }
  *value = v;
  return true;
}

bool OnlyKnown(const QueryParams& params, const std::set<std::string>& known, std::string* error) {
  for (const auto& [name, value] : params) {
    if (!known.count(name)) {
      *error = "unknown parameter '" + name.substr(0, 40) + "'";
      return false;
    }
  }
  return true;
}

void AppendUint(std::string* out, uint64_t v) {
  char buf[24];
  char* p = buf + sizeof(buf);
  do {
    *--p = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v > 0);
  out->append(p, static_cast<size_t>(buf + sizeof(buf) - p));
}

void AppendId(std::string* out, uint64_t packed) {
  const KeyframeId id(packed);
  *out += '"';
  AppendUint(out, id.agent());
  *out += ':';
  AppendUint(out, id.counter());
  *out += '"';
}

/// ",x" with `decimals` fixed decimals; by hand because snprintf("%.3f") was most of the
/// full map's answer time (60,000 points).
void AppendFixed(std::string* out, double x, int decimals) {
  static constexpr int64_t kScale[] = {1, 10, 100, 1000, 10000, 100000};
  char buf[32];
  char* end = buf + sizeof(buf);
  char* p = end;
  if (!std::isfinite(x)) x = 0.0;
  x = std::clamp(x, -1e12, 1e12);  // keeps the scaled value in int64
  const bool negative = x < 0;
  int64_t v = std::llround(std::abs(x) * static_cast<double>(kScale[decimals]));
  for (int i = 0; i < decimals; ++i, v /= 10) *--p = static_cast<char>('0' + v % 10);
  *--p = '.';
  do {
    *--p = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v > 0);
  if (negative) *--p = '-';
  *--p = ',';
  out->append(p, static_cast<size_t>(end - p));
}

// The map answer is written by hand: at 60,000 points a json object per element costs more
// than the 50 ms the API has (docs/map-view.md).
std::string MapDelta(const MapViewSnapshot& s, uint64_t since, int64_t min_weight) {
  const bool reset = since == 0 || since < s.oldest_tombstone;
  const uint64_t after = reset ? 0 : since;
  std::string out;
  out.reserve(256 + 64 * (reset ? s.points.size() + s.keyframes.size() : 64));
  out += "{\"version\":" + std::to_string(s.version) + ",\"since\":" + std::to_string(since) +
         ",\"reset\":" + (reset ? "true" : "false") + ",\"point_stride\":" + std::to_string(s.point_stride) +
         ",\"min_weight\":" + std::to_string(min_weight) + ",\"keyframes\":[";
  bool first = true;
  for (const ViewKeyframe& k : s.keyframes) {
    if (k.changed <= after) continue;
    out += first ? "[" : ",[";
    first = false;
    AppendId(&out, k.id);
    out += ',';
    AppendId(&out, k.map);
    for (int i = 0; i < 7; ++i) AppendFixed(&out, k.pose[i], i < 3 ? 3 : 4);
    out += ']';
  }
  out += "],\"points\":[";
  first = true;
  for (const ViewPoint& p : s.points) {
    if (p.changed <= after) continue;
    out += first ? "[" : ",[";
    first = false;
    AppendId(&out, p.id);
    for (int i = 0; i < 3; ++i) AppendFixed(&out, p.xyz[i], 3);
    out += ']';
  }
  out += "],\"edges\":[";
  std::string weak_edges;  // changed edges below min_weight: removed for this client
  first = true;
  for (const ViewEdge& e : s.edges) {
    if (e.changed <= after) continue;
    if (e.weight < min_weight) {
      if (!reset) {
        weak_edges += weak_edges.empty() ? "[" : ",[";
        AppendId(&weak_edges, e.a);
        weak_edges += ',';
        AppendId(&weak_edges, e.b);
        weak_edges += ']';
      }
      continue;
    }
    out += first ? "[" : ",[";
    first = false;
    AppendId(&out, e.a);
    out += ',';
    AppendId(&out, e.b);
    out += ',' + std::to_string(e.weight) + ']';
  }
  out += "],\"removed\":{\"keyframes\":[";
  auto removed_ids = [&](const std::vector<Tombstone>& list) {
    bool f = true;
    if (reset) return;
    for (const Tombstone& t : list) {
      if (t.version <= after) continue;
      if (!f) out += ',';
      f = false;
      AppendId(&out, t.id);
    }
  };
  removed_ids(s.removed_keyframes);
  out += "],\"points\":[";
  removed_ids(s.removed_points);
  out += "],\"edges\":[";
  bool f = true;
  if (!reset) {
    for (const Tombstone& t : s.removed_edges) {
      if (t.version <= after) continue;
      out += f ? "[" : ",[";
      f = false;
      AppendId(&out, t.id);
      out += ',';
      AppendId(&out, t.b);
      out += ']';
    }
  }
  if (!weak_edges.empty()) out += (f ? "" : ",") + weak_edges;
  out += "]}}";
  return out;
}

nlohmann::json EventJson(const ServerEvent& e, size_t index) {
  nlohmann::json j = {{"index", index},
                      {"kind", ServerEventKindName(e.kind)},
                      {"time_s", std::round(e.time_s * 1000.0) / 1000.0},
                      {"agent", e.agent},
                      {"map", IdText(e.map.packed())},
                      {"keyframes", e.keyframes},
                      {"seconds", std::round(e.seconds * 1000.0) / 1000.0},
                      {"detail", e.detail}};
  if (e.other_map.valid()) j["other_map"] = IdText(e.other_map.packed());
  if (e.query.valid()) j["query"] = IdText(e.query.packed());
  if (e.candidate.valid()) j["candidate"] = IdText(e.candidate.packed());
  return j;
}

}  // namespace

ApiResponse ApiError(int status, const std::string& message) {
  return {status, nlohmann::json{{"error", message}, {"status", status}}.dump()};
}

ApiResponse HandleApiRequest(const MapViewSnapshot& s, const std::string& path, const QueryParams& params,
                             const nlohmann::json& extra_status) {
  std::string error;
  if (path == "/api/status") {
    if (!OnlyKnown(params, {}, &error)) return ApiError(400, error);
    nlohmann::json j = s.status;
    j["version"] = s.version;
    j["server_time_s"] = std::round(s.server_time_s * 1000.0) / 1000.0;
    j["snapshot"] = {{"refresh_ms", s.timing.refresh_ms},
                     {"max_lock_hold_us", s.timing.max_lock_hold_us},
                     {"max_lock_hold_us_ever", s.timing.max_lock_hold_us_ever},
                     {"refreshes", s.timing.refreshes},
                     {"keyframes", s.keyframes.size()},
                     {"points", s.points.size()},
                     {"point_stride", s.point_stride},
                     {"edges", s.edges.size()}};
    for (const auto& [key, value] : extra_status.items()) j[key] = value;
    return {200, j.dump()};
  }
  if (path == "/api/map") {
    int64_t since = 0, min_weight = 0;
    if (!OnlyKnown(params, {"since", "min_weight"}, &error) ||
        !ParseInt(params, "min_weight", 0, kMaxWeight, &min_weight, &error) ||
        !ParseInt(params, "since", 0, static_cast<int64_t>(s.version), &since, &error)) {
      return ApiError(400, error + " (current version " + std::to_string(s.version) + ")");
    }
    return {200, MapDelta(s, static_cast<uint64_t>(since), min_weight)};
  }
  if (path == "/api/events") {
    int64_t since = 0, limit = 1000;
    if (!OnlyKnown(params, {"since", "limit"}, &error) ||
        !ParseInt(params, "since", 0, static_cast<int64_t>(s.events.size()), &since, &error) ||
        !ParseInt(params, "limit", 1, kMaxEventsPerAnswer, &limit, &error)) {
      return ApiError(400, error + " (" + std::to_string(s.events.size()) + " events so far)");
    }
    nlohmann::json list = nlohmann::json::array();
    const size_t end = std::min(s.events.size(), static_cast<size_t>(since + limit));
    for (size_t i = static_cast<size_t>(since); i < end; ++i) list.push_back(EventJson(s.events[i], i));
    return {200, nlohmann::json{{"total", s.events.size()}, {"next", end}, {"events", list}}.dump()};
  }
  return ApiError(404, "no such API path '" + path.substr(0, 100) + "' (see /api/status, /api/map, /api/events)");
}

}  // namespace ccm::server
