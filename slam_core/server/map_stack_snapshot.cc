#include "slam_core/server/map_stack_snapshot.h"

#include <algorithm>
#include <shared_mutex>

namespace ccm {

MapStackSnapshot MapStackSnapshot::Of(const MapStack& stack) {
  MapStackSnapshot s;
  // Maps first, handlers after: persistence leaves out a handler whose map is not in the
  // snapshot, so the file always loads.
  for (auto& m : stack.Maps()) s.maps.push_back(std::move(m));
  s.next_map_counter = stack.next_map_counter();
  s.handlers = stack.Handlers();
  return s;
}

std::shared_ptr<const ServerMap> MapStackSnapshot::Map(MapId id) const {
  for (const auto& m : maps) {
    if (m->id() == id) return m;
  }
  return nullptr;
}

std::shared_ptr<const ServerMap> MapStackSnapshot::MapHolding(KeyframeId kf) const {
  for (const auto& m : maps) {
    if (m->Knows(kf)) return m;
  }
  return nullptr;
}

std::vector<MapSummary> MapStackSnapshot::Summaries() const {
  std::vector<MapSummary> out;
  for (const auto& m : maps) {
    MapSummary s;
    s.id = m->id();
    s.keyframes = m->map().num_keyframes();
    s.map_points = m->map().num_map_points();
    s.anchored = m->anchors().size();
    for (const AgentHandler& h : handlers) {
      if (h.map == m->id()) s.agents.insert(h.agent);
    }
    out.push_back(s);
  }
  return out;
}

std::vector<ServerKeyframePose> MapStackSnapshot::AgentTrajectory(AgentId agent) const {
  std::vector<ServerKeyframePose> out;
  for (const auto& m : maps) {
    std::shared_lock<WriterPreferringMutex> lock(m->structure_mutex());
    for (const auto& [id, info] : m->infos()) {
      const auto kf = id.agent() == agent ? m->map().keyframe(id) : nullptr;
      if (kf) out.push_back({id, m->id(), info.segment, kf->stamp_ns(), kf->world_from_cam(), true});
    }
    for (const auto& [id, anchor] : m->anchors()) {
      if (id.agent() != agent) continue;
      if (const auto pose = m->PoseOf(id)) out.push_back({id, m->id(), anchor.segment, anchor.stamp_ns, *pose, false});
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
  return out;
}

std::vector<RevisitLink> MapStackSnapshot::AgentRevisitLinks(AgentId agent, int64_t min_gap_ns,
                                                             int min_shared) const {
  std::vector<RevisitLink> out;
  for (const auto& m : maps) {
    std::shared_lock<WriterPreferringMutex> lock(m->structure_mutex());
    for (const auto& [id, info] : m->infos()) {
      const auto late = id.agent() == agent ? m->map().keyframe(id) : nullptr;
      if (!late) continue;
      for (const auto& [other, weight] : late->covisibility()) {
        if (other.agent() != agent || weight < min_shared) continue;
        const auto early = m->map().keyframe(other);
        if (!early || early->stamp_ns() + min_gap_ns > late->stamp_ns()) continue;
        out.push_back({other, id, early->stamp_ns(), late->stamp_ns(), weight});
      }
    }
  }
  return out;
}

}  // namespace ccm
