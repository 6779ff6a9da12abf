#include "slam_core/server/server_map.h"

namespace ccm {

void ServerMap::SetInfo(KeyframeId id, const ServerKeyframeInfo& info) {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  info_[id] = info;
}

std::optional<ServerKeyframeInfo> ServerMap::Info(KeyframeId id) const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  const auto it = info_.find(id);
  if (it == info_.end()) return std::nullopt;
  return it->second;
}

void ServerMap::MarkSettled(const std::vector<KeyframeId>& ids) {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  for (const KeyframeId id : ids) {
    if (const auto it = info_.find(id); it != info_.end()) it->second.settled = true;
  }
}

void ServerMap::EraseInfo(KeyframeId id) {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  info_.erase(id);
}

void ServerMap::AddAnchor(KeyframeId id, const KeyframeAnchor& anchor) {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  anchors_[id] = anchor;
}

std::optional<KeyframeAnchor> ServerMap::Anchor(KeyframeId id) const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  const auto it = anchors_.find(id);
  if (it == anchors_.end()) return std::nullopt;
  return it->second;
}

std::unordered_map<KeyframeId, KeyframeAnchor> ServerMap::anchors() const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  return anchors_;
}

std::optional<SE3> ServerMap::PoseOf(KeyframeId id) const {
  SE3 base_from_cam;
  // Anchors chain when a base was itself removed later; the chain is short and acyclic
  // (an anchor's base was in the map when it was anchored), the cap guards corrupted input.
  for (int hop = 0; hop < 64; ++hop) {
    if (const auto kf = map_.keyframe(id)) return kf->world_from_cam() * base_from_cam;
    const auto anchor = Anchor(id);
    if (!anchor) return std::nullopt;
    base_from_cam = anchor->base_from_cam * base_from_cam;
    id = anchor->base;
  }
  return std::nullopt;
}

KeyframeId ServerMap::AnchorRoot(KeyframeId id) const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  for (int hop = 0; hop < 64; ++hop) {  // acyclic and short (see PoseOf); the cap guards corruption
    const auto it = anchors_.find(id);
    if (it == anchors_.end()) break;
    id = it->second.base;
  }
  return id;
}

bool ServerMap::Knows(KeyframeId id) const {
  if (map_.keyframe(id)) return true;
  std::lock_guard<std::mutex> lock(tables_mutex_);
  return anchors_.count(id) > 0;
}

void ServerMap::RecordReplacement(MapPointId old_id, MapPointId keep) {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  replaced_[old_id] = keep;
}

MapPointId ServerMap::Resolve(MapPointId id) const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  for (int hop = 0; hop < 64; ++hop) {
    const auto it = replaced_.find(id);
    if (it == replaced_.end()) return id;
    id = it->second;
  }
  return id;
}

void ServerMap::RescaleAnchors(const std::function<double(KeyframeId root)>& scale_of) {
  // Roots and scales outside the table lock: scale_of may look at the map.
  std::unordered_map<KeyframeId, double> scale;
  for (const auto& [id, anchor] : anchors()) {
    const double s = scale_of(AnchorRoot(anchor.base));
    if (s != 1.0) scale[id] = s;
  }
  std::lock_guard<std::mutex> lock(tables_mutex_);
  for (const auto& [id, s] : scale) {
    const auto it = anchors_.find(id);
    if (it == anchors_.end()) continue;
    SE3& T = it->second.base_from_cam;
    T = SE3(T.rotation(), s * T.translation());
  }
}

void ServerMap::AbsorbTables(ServerMap* other) {
  std::scoped_lock lock(tables_mutex_, other->tables_mutex_);
  info_.merge(other->info_);
  anchors_.merge(other->anchors_);
  replaced_.merge(other->replaced_);
}

std::unordered_map<KeyframeId, ServerKeyframeInfo> ServerMap::infos() const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  return info_;
}

std::unordered_map<MapPointId, MapPointId> ServerMap::replacements() const {
  std::lock_guard<std::mutex> lock(tables_mutex_);
  return replaced_;
}

}  // namespace ccm
