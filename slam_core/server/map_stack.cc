#include "slam_core/server/map_stack.h"

namespace ccm {

std::shared_ptr<ServerMap> MapStack::MapFor(AgentId agent, MapId segment, bool* created) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (created) *created = false;
  const auto key = std::make_pair(agent, segment);
  if (const auto it = handlers_.find(key); it != handlers_.end()) {
    const auto m = maps_.find(it->second.map);
    return m == maps_.end() ? nullptr : m->second;
  }
  auto map = std::make_shared<ServerMap>(MapId::Make(kServerAgent, next_map_++), map_options_);
  maps_.emplace(map->id(), map);
  AgentHandler h;
  h.agent = agent;
  h.segment = segment;
  h.map = map->id();
  handlers_.emplace(key, h);
  if (created) *created = true;
  return map;
}

std::optional<AgentHandler> MapStack::Handler(AgentId agent, MapId segment) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = handlers_.find({agent, segment});
  if (it == handlers_.end()) return std::nullopt;
  return it->second;
}

void MapStack::EditHandler(AgentId agent, MapId segment, const std::function<void(AgentHandler*)>& edit) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = handlers_.find({agent, segment});
  if (it != handlers_.end()) edit(&it->second);
}

std::vector<AgentHandler> MapStack::Handlers() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<AgentHandler> out;
  for (const auto& [key, h] : handlers_) out.push_back(h);
  return out;
}

std::vector<AgentHandler> MapStack::HandlersOfMap(MapId map) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<AgentHandler> out;
  for (const auto& [key, h] : handlers_) {
    if (h.map == map) out.push_back(h);
  }
  return out;
}

std::vector<AgentHandler> MapStack::HandlersOfAgent(AgentId agent) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<AgentHandler> out;
  for (const auto& [key, h] : handlers_) {
    if (h.agent == agent) out.push_back(h);
  }
  return out;
}

std::shared_ptr<ServerMap> MapStack::GetMap(MapId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = maps_.find(id);
  return it == maps_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<ServerMap>> MapStack::Maps() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::shared_ptr<ServerMap>> out;
  for (const auto& [id, m] : maps_) out.push_back(m);
  return out;
}

size_t MapStack::num_maps() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return maps_.size();
}

std::shared_ptr<ServerMap> MapStack::MapHolding(KeyframeId kf) const {
  for (const auto& m : Maps()) {  // a handful of maps: a scan is cheaper than an index to keep
    if (m->Knows(kf)) return m;
  }
  return nullptr;
}

void MapStack::Repoint(MapId from, MapId into, const Sim3& into_from_from) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& [key, h] : handlers_) {
    if (h.map != from) continue;
    h.map = into;
    h.map_from_segment = into_from_from * h.map_from_segment;
    h.scale *= into_from_from.scale();
  }
  maps_.erase(from);
}

void MapStack::RestoreMap(std::shared_ptr<ServerMap> map) {
  std::lock_guard<std::mutex> lock(mutex_);
  maps_[map->id()] = std::move(map);
}

void MapStack::RestoreHandler(const AgentHandler& handler) {
  std::lock_guard<std::mutex> lock(mutex_);
  handlers_[{handler.agent, handler.segment}] = handler;
}

uint64_t MapStack::next_map_counter() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_map_;
}

void MapStack::set_next_map_counter(uint64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  next_map_ = n;
}

}  // namespace ccm
