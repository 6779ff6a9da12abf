// MapViewModel::BuildStatus: the team's status part of a snapshot (agents with their
// current pose, maps, totals, queues, the host's facts). Kept apart from the map copy.
#include <cmath>

#include "server_runtime/map_view_snapshot.h"

namespace ccm::server {
namespace {

double Round(double x, double unit) { return std::round(x / unit) * unit; }

nlohmann::json PoseJson(const SE3& pose) {
  const Eigen::Vector3d& t = pose.translation();
  const Eigen::Quaterniond& q = pose.rotation();
  return {Round(t.x(), 1e-3), Round(t.y(), 1e-3), Round(t.z(), 1e-3),
          Round(q.x(), 1e-4), Round(q.y(), 1e-4), Round(q.z(), 1e-4), Round(q.w(), 1e-4)};
}

}  // namespace

void MapViewModel::BuildStatus(const MapStackSnapshot& stack, MapViewSnapshot* next, double* max_hold_us) {
  auto timed = [max_hold_us](auto&& f) {
    const auto t0 = std::chrono::steady_clock::now();
    auto r = f();
    *max_hold_us = std::max(*max_hold_us,
                            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    return r;
  };
  const auto maps = timed([&] { return stack.Summaries(); });
  const auto& handlers = stack.handlers;
  const auto status = timed([&] { return backend_->Status(); });
  const BackendStats& stats = status.stats;
  const QueueDepths& queues = status.queues;

  nlohmann::json agents = nlohmann::json::object();
  // The agent's newest registered keyframe (largest stamp over its segments) is where the
  // view draws its camera: the server knows no pose newer than that.
  std::map<AgentId, int64_t> newest_stamp;
  for (const AgentHandler& h : handlers) {
    const std::string key = std::to_string(h.agent);
    nlohmann::json& a = agents[key];
    if (!a.contains("id")) {
      a = {{"id", h.agent}, {"keyframes", 0}, {"segments", 0}, {"maps", nlohmann::json::array()}};
    }
    a["keyframes"] = a["keyframes"].get<int64_t>() + h.keyframes;
    a["segments"] = a["segments"].get<int>() + 1;
    const std::string map_text = IdText(h.map.packed());
    if (std::find(a["maps"].begin(), a["maps"].end(), map_text) == a["maps"].end()) a["maps"].push_back(map_text);
    if (!h.last_keyframe.valid()) continue;
    const auto map = stack.Map(h.map);
    if (!map) continue;
    const auto kf = timed([&] { return map->map().keyframe(h.last_keyframe); });
    int64_t stamp = 0;
    std::optional<SE3> pose;
    if (kf) {
      stamp = kf->stamp_ns();
      pose = timed([&] { return kf->world_from_cam(); });
    } else if (const auto anchor = timed([&] { return map->Anchor(h.last_keyframe); })) {
      stamp = anchor->stamp_ns;
      pose = timed([&] { return map->PoseOf(h.last_keyframe); });
    }
    if (!pose || (newest_stamp.count(h.agent) && newest_stamp[h.agent] >= stamp)) continue;
    newest_stamp[h.agent] = stamp;
    a["pose"] = PoseJson(*pose);
    a["map"] = map_text;
    a["last_keyframe"] = IdText(h.last_keyframe.packed());
    a["stamp_s"] = Round(stamp * 1e-9, 1e-3);
  }
  for (auto& [key, a] : agents.items()) {
    const AgentId id = static_cast<AgentId>(a["id"].get<int>());
    if (const auto it = stats.agents.find(id); it != stats.agents.end()) {
      a["registered"] = it->second.keyframes_registered;
      a["duplicates"] = it->second.keyframes_duplicate;
      a["rejected"] = it->second.rejected;
      a["batches_dropped"] = it->second.batches_dropped;
    }
    if (const auto it = queues.agent_batches.find(id); it != queues.agent_batches.end()) a["queue"] = it->second;
    if (const auto it = queues.agent_bytes.find(id); it != queues.agent_bytes.end()) a["queue_bytes"] = it->second;
    if (const auto it = queues.agent_lag_s.find(id); it != queues.agent_lag_s.end()) a["lag_s"] = Round(it->second, 1e-3);
  }
  nlohmann::json host = nlohmann::json::object();
  try {
    if (host_status_) host = host_status_();
  } catch (const std::exception& e) {  // the view stays up; the panel shows why facts are missing
    host = {{"error", std::string("host status failed: ") + e.what()}};
  }
  if (host.is_object() && host.contains("agents") && host["agents"].is_object()) {
    for (auto& [key, extra] : host["agents"].items()) {
      const bool numeric = !key.empty() && key.size() <= 5 && key.find_first_not_of("0123456789") == std::string::npos;
      if (!numeric || !extra.is_object()) continue;  // agents are keyed by their id
      if (!agents.contains(key)) agents[key] = {{"id", std::stoi(key)}, {"keyframes", 0}};
      agents[key].update(extra);
    }
    host.erase("agents");
  }

  double global_ba_s = 0.0;
  for (const auto& [kfs, seconds] : stats.global_ba_seconds) global_ba_s += seconds;
  nlohmann::json map_list = nlohmann::json::array();
  size_t keyframes = 0, points = 0;
  for (const MapSummary& m : maps) {
    nlohmann::json ids = nlohmann::json::array();
    for (AgentId a : m.agents) ids.push_back(a);
    map_list.push_back({{"id", IdText(m.id.packed())}, {"keyframes", m.keyframes}, {"map_points", m.map_points},
                        {"anchored", m.anchored}, {"agents", ids}});
    keyframes += m.keyframes;
    points += m.map_points;
  }
  nlohmann::json agent_list = nlohmann::json::array();
  for (auto& [key, a] : agents.items()) agent_list.push_back(a);
  std::sort(agent_list.begin(), agent_list.end(),
            [](const nlohmann::json& x, const nlohmann::json& y) { return x["id"].get<int>() < y["id"].get<int>(); });
  next->status = {
      {"agents", agent_list},
      {"maps", map_list},
      {"totals",
       {{"agents", agent_list.size()},
        {"maps", maps.size()},
        {"keyframes", keyframes},
        {"map_points", points},
        {"fusions", stats.fusions},
        {"loops", stats.loops},
        {"global_bas", stats.global_ba_applied},
        {"global_ba_seconds", Round(global_ba_s, 1e-3)},
        {"keyframes_removed", stats.keyframes_removed},
        {"events", next->events.size()}}},
      {"queues",
       {{"place_recognition", queues.place_recognition},
        {"global_ba_pending", queues.global_ba_pending},
        {"global_ba_running", queues.global_ba_running}}},
      {"host", host}};
}

}  // namespace ccm::server
