#include "server_runtime/status_format.h"

#include <spdlog/fmt/fmt.h>

namespace ccm::server {
namespace {

const char* TrackingName(int state) {
  switch (state) {
    case 0: return "not initialized";
    case 1: return "ok";
    case 2: return "lost";
    case 3: return "relocalized";
    default: return "?";
  }
}

// Map ids pack the agent that created the map (16 bits) and its counter (48 bits).
std::string MapName(uint64_t packed) { return fmt::format("{}:{}", packed >> 48, packed & ((uint64_t{1} << 48) - 1)); }

}  // namespace

nlohmann::json StatusToJson(const status::ServerStatus& s) {
  nlohmann::json j;
  j["stamp_ns"] = s.stamp_ns();
  j["uptime_s"] = s.uptime_s();
  j["pid"] = s.pid();
  j["map_file"] = s.map_file().to_string();
  j["last_save_s"] = s.last_save_s();
  j["fusions"] = s.fusions();
  j["loops"] = s.loops();
  j["global_bas"] = s.global_bas();
  j["queues"] = {{"place_recognition", s.place_recognition_queue()},
                 {"global_ba_pending", s.global_ba_pending()},
                 {"global_ba_running", s.global_ba_running()}};
  j["refused_agents"] = s.refused_agents();
  j["rejected"] = s.rejected();
  j["agents"] = nlohmann::json::array();
  for (const auto& a : s.agents()) {
    j["agents"].push_back({{"agent_id", a.agent_id()},
                           {"alive", a.alive()},
                           {"last_seen_s", a.last_seen_s()},
                           {"keyframes_received", a.keyframes_received()},
                           {"map_points_received", a.map_points_received()},
                           {"keyframes_registered", a.keyframes_registered()},
                           {"rejected", a.rejected()},
                           {"batches_dropped", a.batches_dropped()},
                           {"queued_batches", a.queued_batches()},
                           {"kfs_acked", a.kfs_acked()},
                           {"kfs_unacked", a.kfs_unacked()},
                           {"kfs_lost", a.kfs_lost()},
                           {"tracking", TrackingName(a.tracking_state())}});
  }
  j["maps"] = nlohmann::json::array();
  for (const auto& m : s.maps()) {
    j["maps"].push_back({{"map", MapName(m.map_id())},
                         {"keyframes", m.keyframes()},
                         {"map_points", m.map_points()},
                         {"anchored", m.anchored()},
                         {"agents", m.agents()}});
  }
  j["traffic"] = nlohmann::json::array();
  for (const auto& t : s.traffic()) {
    j["traffic"].push_back({{"topic", t.topic().to_string()},
                            {"direction", t.direction().to_string()},
                            {"samples", t.samples()},
                            {"bytes", t.bytes()},
                            {"lost", t.lost()}});
  }
  return j;
}

std::string StatusToText(const status::ServerStatus& s) {
  std::string out = fmt::format("ccm_server pid {}, up {:.0f} s; map file {}", s.pid(), s.uptime_s(),
                                s.map_file().size() == 0 ? std::string("(none)") : s.map_file().to_string());
  out += s.last_save_s() >= 0.0 ? fmt::format(" (saved at {:.0f} s)\n", s.last_save_s()) : std::string(" (not saved yet)\n");
  out += fmt::format("fusions {}, loops {}, global BAs {}; queues: place recognition {}, global BA {}{}\n", s.fusions(),
                     s.loops(), s.global_bas(), s.place_recognition_queue(), s.global_ba_pending(),
                     s.global_ba_running() ? " (one running)" : "");
  if (s.refused_agents() > 0 || s.rejected() > 0) {
    out += fmt::format("refused agent messages {}, rejected messages {}\n", s.refused_agents(), s.rejected());
  }
  out += fmt::format("agents ({}):\n", s.agents().size());
  for (const auto& a : s.agents()) {
    out += fmt::format("  {:>5} {:<5} seen {:>6.1f} s  KFs rx {:>5} reg {:>5}  acked {:>5} unacked {:>3} lost {:>3}"
                       "  queue {:>3}  tracking {}\n",
                       a.agent_id(), a.alive() ? "up" : "gone", a.last_seen_s(), a.keyframes_received(),
                       a.keyframes_registered(), a.kfs_acked(), a.kfs_unacked(), a.kfs_lost(), a.queued_batches(),
                       TrackingName(a.tracking_state()));
  }
  out += fmt::format("maps ({}):\n", s.maps().size());
  for (const auto& m : s.maps()) {
    std::string agents;
    for (uint16_t a : m.agents()) agents += (agents.empty() ? "" : ",") + std::to_string(a);
    out += fmt::format("  {:>10}  KFs {:>5} (+{} anchored)  points {:>6}  agents {}\n", MapName(m.map_id()),
                       m.keyframes(), m.anchored(), m.map_points(), agents);
  }
  out += "traffic:\n";
  for (const auto& t : s.traffic()) {
    out += fmt::format("  {:<3} {:<36} {:>8} samples {:>12} B  lost {}\n", t.direction().to_string(),
                       t.topic().to_string(), t.samples(), t.bytes(), t.lost());
  }
  return out;
}

}  // namespace ccm::server
