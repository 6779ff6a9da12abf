#include "server_runtime/server_status.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>

#include "runtime_common/topics.h"
#include "runtime_common/wall_clock.h"

namespace ccm::server {

status::ServerStatus MakeServerStatus(const ServerBackend& backend, const ServerCommStats& comm,
                                      const std::vector<rt::TopicCountersSnapshot>& traffic, const DaemonInfo& info) {
  status::ServerStatus s;
  s.stamp_ns(rt::WallClockNs());
  s.uptime_s(info.uptime_s);
  s.pid(static_cast<uint32_t>(getpid()));
  s.map_file(info.map_file.substr(0, 511));
  s.last_save_s(info.last_save_s);
  const BackendStatus status = backend.Status();
  const BackendStats& stats = status.stats;
  const QueueDepths& queues = status.queues;
  s.fusions(stats.fusions);
  s.loops(stats.loops);
  s.global_bas(stats.global_ba_applied);
  s.place_recognition_queue(static_cast<uint32_t>(queues.place_recognition));
  s.global_ba_pending(static_cast<uint32_t>(queues.global_ba_pending));
  s.global_ba_running(queues.global_ba_running);
  s.refused_agents(comm.refused_agents);
  s.rejected(comm.rejected);
  for (const auto& [id, link] : comm.agents) {
    if (s.agents().size() >= status::kMaxStatusAgents) break;
    status::AgentEntry a;
    a.agent_id(static_cast<uint16_t>(id));
    a.alive(link.alive);
    a.last_seen_s(link.last_seen_s);
    a.keyframes_received(link.keyframes);
    a.map_points_received(link.map_points);
    const auto c = stats.agents.find(id);
    if (c != stats.agents.end()) {
      a.keyframes_registered(c->second.keyframes_registered);
      a.batches_dropped(c->second.batches_dropped);
    }
    a.rejected(link.rejected);
    const auto q = queues.agent_batches.find(id);
    a.queued_batches(q == queues.agent_batches.end() ? 0 : static_cast<uint32_t>(q->second));
    a.kfs_acked(link.kfs_acked);
    a.kfs_unacked(link.kfs_sent >= link.kfs_acked ? link.kfs_sent - link.kfs_acked : 0);
    a.kfs_lost(link.kfs_lost);
    a.tracking_state(static_cast<uint8_t>(link.tracking_state));
    s.agents().push_back(a);
  }
  for (const MapSummary& m : backend.Snapshot().Summaries()) {
    if (s.maps().size() >= status::kMaxStatusMaps) break;
    status::MapEntry e;
    e.map_id(m.id.packed());
    e.keyframes(static_cast<uint32_t>(m.keyframes));
    e.map_points(static_cast<uint32_t>(m.map_points));
    e.anchored(static_cast<uint32_t>(m.anchored));
    for (AgentId a : m.agents) e.agents().push_back(static_cast<uint16_t>(a));
    s.maps().push_back(e);
  }
  for (const auto& t : traffic) {
    if (s.traffic().size() >= status::kMaxStatusTopics) break;
    status::TopicTraffic e;
    e.topic(t.topic.substr(0, 95));
    e.direction(t.direction.substr(0, 3));
    e.samples(t.samples);
    e.bytes(t.payload_bytes);
    e.lost(t.direction == "in" ? t.samples_lost : t.write_failures);
    s.traffic().push_back(e);
  }
  return s;
}

std::unique_ptr<StatusPublisher> StatusPublisher::Create(rt::DdsSession& session, std::string* error) {
  std::unique_ptr<StatusPublisher> p(new StatusPublisher());
  p->writer_ = rt::TypedWriter<status::ServerStatusPubSubType>::Create(session, rt::kTopicServerStatus,
                                                                        rt::kProfileServerStatusWriter, error);
  if (!p->writer_) return nullptr;
  return p;
}

}  // namespace ccm::server
