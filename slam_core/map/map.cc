#include "slam_core/map/map.h"

#include <algorithm>
#include <limits>

namespace ccm {

std::string MapOptions::Validate() const {
  if (covisibility_min_shared < 1) return "covisibility_min_shared must be >= 1";
  if (essential_min_weight < covisibility_min_shared) {
    return "essential_min_weight must be >= covisibility_min_shared";
  }
  return "";
}

Map::Map(MapId id, MapOptions options) : id_(id), options_(options) {}

bool Map::AddKeyframe(std::shared_ptr<KeyFrame> kf) {
  std::unique_lock<std::shared_mutex> lock(tables_mutex_);
  return keyframes_.emplace(kf->id(), std::move(kf)).second;
}

bool Map::AddMapPoint(std::shared_ptr<MapPoint> mp) {
  std::unique_lock<std::shared_mutex> lock(tables_mutex_);
  return map_points_.emplace(mp->id(), std::move(mp)).second;
}

std::shared_ptr<KeyFrame> Map::keyframe(KeyframeId id) const {
  std::shared_lock<std::shared_mutex> lock(tables_mutex_);
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : it->second;
}

std::shared_ptr<MapPoint> Map::map_point(MapPointId id) const {
  std::shared_lock<std::shared_mutex> lock(tables_mutex_);
  const auto it = map_points_.find(id);
  return it == map_points_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<MapPoint>> Map::map_points(const std::vector<MapPointId>& ids) const {
  std::vector<std::shared_ptr<MapPoint>> out;
  out.reserve(ids.size());
  std::shared_lock<std::shared_mutex> lock(tables_mutex_);
  for (const MapPointId id : ids) {
    const auto it = map_points_.find(id);
    out.push_back(it == map_points_.end() ? nullptr : it->second);
  }
  return out;
}

std::vector<std::shared_ptr<KeyFrame>> Map::keyframes() const {
  std::vector<std::shared_ptr<KeyFrame>> out;
  {
    std::shared_lock<std::shared_mutex> lock(tables_mutex_);
    out.reserve(keyframes_.size());
    for (const auto& [id, kf] : keyframes_) out.push_back(kf);
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a->id() < b->id(); });
  return out;
}

std::vector<std::shared_ptr<MapPoint>> Map::map_points() const {
  std::vector<std::shared_ptr<MapPoint>> out;
  {
    std::shared_lock<std::shared_mutex> lock(tables_mutex_);
    out.reserve(map_points_.size());
    for (const auto& [id, mp] : map_points_) out.push_back(mp);
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a->id() < b->id(); });
  return out;
}

size_t Map::num_keyframes() const {
  std::shared_lock<std::shared_mutex> lock(tables_mutex_);
  return keyframes_.size();
}

size_t Map::num_map_points() const {
  std::shared_lock<std::shared_mutex> lock(tables_mutex_);
  return map_points_.size();
}

bool Map::AddObservation(KeyframeId kf_id, int keypoint, MapPointId mp_id) {
  const auto kf = keyframe(kf_id);
  const auto mp = map_point(mp_id);
  if (!kf || !mp || keypoint < 0 || static_cast<size_t>(keypoint) >= kf->num_keypoints()) return false;
  const MapPointId current = kf->MapPointAt(keypoint);
  if (current.valid() && current != mp_id) return false;
  if (!mp->AddObservation(kf_id, keypoint)) return current == mp_id;
  kf->SetMapPointAt(keypoint, mp_id);
  return true;
}

void Map::EraseObservation(KeyframeId kf_id, MapPointId mp_id) {
  const auto kf = keyframe(kf_id);
  const auto mp = map_point(mp_id);
  if (!mp) return;
  const auto idx = mp->KeypointIn(kf_id);
  if (!idx) return;
  mp->EraseObservation(kf_id);
  if (kf) kf->ClearMapPointAt(*idx, mp_id);
  if (mp->num_observations() == 0) {
    EraseMapPoint(mp_id);
  } else if (mp->reference_kf() == kf_id) {
    mp->SetReferenceKf(mp->observations().front().first);
  }
}

void Map::UpdateConnections(KeyframeId kf_id) {
  std::lock_guard<std::mutex> graph_lock(graph_mutex_);
  const auto kf = keyframe(kf_id);
  if (!kf) return;
  std::map<KeyframeId, int> counts;
  for (const MapPointId mp_id : kf->map_points()) {
    if (!mp_id.valid()) continue;
    const auto mp = map_point(mp_id);
    if (!mp || mp->bad()) continue;
    for (const auto& [other, idx] : mp->observations()) {
      if (other != kf_id) ++counts[other];
    }
  }
  std::map<KeyframeId, int> edges;
  KeyframeId best;
  int best_count = 0;
  for (const auto& [other, n] : counts) {
    if (!keyframe(other)) continue;
    if (n > best_count) best_count = n, best = other;
    if (n >= options_.covisibility_min_shared) edges[other] = n;
  }
  // Like ORB-SLAM: a keyframe with no strong neighbour keeps its strongest weak one, so
  // the graph stays connected.
  if (edges.empty() && best.valid()) edges[best] = best_count;

  for (const auto& [old_neighbour, w] : kf->covisibility()) {
    if (edges.count(old_neighbour)) continue;
    if (const auto n = keyframe(old_neighbour)) n->SetCovisibilityWeight(kf_id, 0);
  }
  for (const auto& [neighbour, w] : edges) keyframe(neighbour)->SetCovisibilityWeight(kf_id, w);
  kf->SetCovisibility(edges);

  if (!kf->parent().valid() && best.valid()) {
    // The parent must be an existing tree member; prefer the strongest neighbour.
    const auto parent = keyframe(kf->BestCovisible(1).front());
    if (parent && !parent->bad() && parent->parent() != kf_id) {
      kf->SetParent(parent->id());
      parent->AddChild(kf_id);
    }
  }
}

void Map::AddLoopEdge(KeyframeId a, KeyframeId b) {
  std::lock_guard<std::mutex> graph_lock(graph_mutex_);
  const auto ka = keyframe(a), kb = keyframe(b);
  if (!ka || !kb || a == b) return;
  ka->AddLoopEdge(b);
  kb->AddLoopEdge(a);
}

void Map::ReparentChildren(const std::shared_ptr<KeyFrame>& erased) {
  // ORB-SLAM's repair: grow the set of possible parents (the erased node's parent plus
  // already re-attached children) and repeatedly attach the child with the strongest
  // covisibility edge into that set.
  std::set<KeyframeId> children = erased->children();
  std::set<KeyframeId> candidates;
  KeyframeId new_root;
  if (erased->parent().valid()) {
    candidates.insert(erased->parent());
  } else if (!children.empty()) {
    // Erasing the root: its strongest child becomes the new root.
    KeyframeId best = *children.begin();
    int best_w = -1;
    for (const KeyframeId c : children) {
      const int w = erased->CovisibilityWeight(c);
      if (w > best_w) best_w = w, best = c;
    }
    new_root = best;
    children.erase(best);
    candidates.insert(best);
    if (const auto r = keyframe(best)) r->SetParent(KeyframeId::Invalid());
  }
  while (!children.empty()) {
    int best_w = 0;
    KeyframeId best_child, best_parent;
    for (const KeyframeId c : children) {
      const auto child = keyframe(c);
      if (!child) continue;
      for (const auto& [n, w] : child->covisibility()) {
        if (candidates.count(n) && w > best_w) best_w = w, best_child = c, best_parent = n;
      }
    }
    if (!best_child.valid()) break;
    keyframe(best_child)->SetParent(best_parent);
    keyframe(best_parent)->AddChild(best_child);
    candidates.insert(best_child);
    children.erase(best_child);
  }
  // Children without a covisible candidate hang from the erased node's parent (or the new root).
  const KeyframeId fallback = erased->parent().valid() ? erased->parent() : new_root;
  for (const KeyframeId c : children) {
    const auto child = keyframe(c);
    const auto parent = keyframe(fallback);
    if (!child) continue;
    child->SetParent(parent ? fallback : KeyframeId::Invalid());
    if (parent) parent->AddChild(c);
  }
}

bool Map::EraseKeyframe(KeyframeId kf_id) {
  std::lock_guard<std::mutex> graph_lock(graph_mutex_);
  const auto kf = keyframe(kf_id);
  if (!kf) return false;
  kf->SetBad();
  for (const auto& [n, w] : kf->covisibility()) {
    if (const auto nk = keyframe(n)) nk->SetCovisibilityWeight(kf_id, 0);
  }
  // Loop edges of the other side stay as a record; BuildEssentialGraph skips absent ends.
  ReparentChildren(kf);
  if (const auto parent = keyframe(kf->parent())) parent->EraseChild(kf_id);
  const std::vector<MapPointId> mps = kf->map_points();
  for (size_t i = 0; i < mps.size(); ++i) {
    if (!mps[i].valid()) continue;
    const auto mp = map_point(mps[i]);
    kf->ClearMapPointAt(i, mps[i]);
    if (!mp) continue;
    mp->EraseObservation(kf_id);
    if (mp->num_observations() == 0) {
      EraseMapPointLocked(mp);
    } else if (mp->reference_kf() == kf_id) {
      mp->SetReferenceKf(mp->observations().front().first);
    }
  }
  std::unique_lock<std::shared_mutex> lock(tables_mutex_);
  keyframes_.erase(kf_id);
  return true;
}

void Map::EraseMapPointLocked(const std::shared_ptr<MapPoint>& mp) {
  for (const auto& [kf_id, idx] : mp->observations()) {
    if (const auto kf = keyframe(kf_id)) kf->ClearMapPointAt(idx, mp->id());
    mp->EraseObservation(kf_id);
  }
  if (!mp->bad()) mp->SetBad();
  std::unique_lock<std::shared_mutex> lock(tables_mutex_);
  map_points_.erase(mp->id());
}

bool Map::EraseMapPoint(MapPointId mp_id) {
  const auto mp = map_point(mp_id);
  if (!mp) return false;
  EraseMapPointLocked(mp);
  return true;
}

bool Map::ReplaceMapPoint(MapPointId old_id, MapPointId keep_id) {
  if (old_id == keep_id) return false;
  const auto old_mp = map_point(old_id), keep = map_point(keep_id);
  if (!old_mp || !keep) return false;
  for (const auto& [kf_id, idx] : old_mp->observations()) {
    const auto kf = keyframe(kf_id);
    old_mp->EraseObservation(kf_id);
    if (!kf) continue;
    if (keep->KeypointIn(kf_id)) {
      kf->ClearMapPointAt(idx, old_id);  // the keyframe already sees the kept point
    } else {
      kf->SetMapPointAt(idx, keep_id);
      keep->AddObservation(kf_id, idx);
    }
  }
  old_mp->SetBad(keep_id);
  {
    std::unique_lock<std::shared_mutex> lock(tables_mutex_);
    map_points_.erase(old_id);
  }
  UpdateMapPointAppearance(keep_id);
  return true;
}

void Map::UpdateMapPointAppearance(MapPointId mp_id) {
  const auto mp = map_point(mp_id);
  if (!mp) return;
  std::uint64_t stamp = 0;
  const auto obs = mp->observations(&stamp);
  if (obs.empty()) return;
  const Eigen::Vector3d p = mp->position();
  std::vector<OrbDescriptor> descs;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (const auto& [kf_id, idx] : obs) {
    const auto kf = keyframe(kf_id);
    if (!kf) continue;
    descs.push_back(kf->features().descriptors[idx]);
    normal += (p - kf->camera_center()).normalized();
  }
  if (descs.empty()) return;
  // The descriptor depends only on the observations (and which of their keyframes this map
  // holds): after a BA moved the point it stays, and the quadratic search below, most of the
  // cost of an update, is skipped.
  const std::uint64_t basis = (stamp << 16) | (descs.size() & 0xffff);
  const bool same_descriptor = mp->DescriptorBasedOn(basis);
  // Representative descriptor: the one with the smallest median distance to the others.
  size_t best = 0;
  int best_median = std::numeric_limits<int>::max();
  for (size_t i = 0; !same_descriptor && i < descs.size(); ++i) {
    std::vector<int> d;
    for (size_t j = 0; j < descs.size(); ++j) d.push_back(HammingDistance(descs[i], descs[j]));
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    if (d[d.size() / 2] < best_median) best_median = d[d.size() / 2], best = i;
  }
  // Depth range: distance to the reference keyframe, widened by the pyramid so the point
  // matches at any level it could appear on (ORB-SLAM's rule).
  double max_d = 0, min_d = 0;
  const auto ref = keyframe(mp->reference_kf());
  if (const auto ref_idx = ref ? mp->KeypointIn(ref->id()) : std::nullopt) {
    const ScalePyramid& pyr = ref->pyramid();
    const double dist = (p - ref->camera_center()).norm();
    const int level = ref->features().keypoints[*ref_idx].level;
    max_d = dist * pyr.scale[level];
    min_d = max_d / pyr.scale[pyr.num_levels - 1];
  }
  mp->SetAppearance(same_descriptor ? mp->descriptor() : descs[best], normal.normalized(), min_d, max_d, basis);
}

EssentialGraph Map::BuildEssentialGraph() const {
  std::lock_guard<std::mutex> graph_lock(graph_mutex_);
  EssentialGraph g;
  for (const auto& kf : keyframes()) {
    g.nodes.push_back(kf->id());
    const KeyframeId parent = kf->parent();
    if (parent.valid() && keyframe(parent)) {
      g.edges.push_back({kf->id(), parent, EssentialGraph::EdgeType::kSpanningTree, kf->CovisibilityWeight(parent)});
    }
    for (const auto& [n, w] : kf->covisibility()) {
      // Once per undirected edge, and not again if it already is a tree edge.
      if (!(kf->id() < n) || w < options_.essential_min_weight) continue;
      if (parent == n) continue;
      const auto nk = keyframe(n);
      if (!nk || nk->parent() == kf->id()) continue;
      g.edges.push_back({kf->id(), n, EssentialGraph::EdgeType::kCovisibility, w});
    }
    for (const KeyframeId other : kf->loop_edges()) {
      if (kf->id() < other && keyframe(other)) {
        g.edges.push_back({kf->id(), other, EssentialGraph::EdgeType::kLoop, kf->CovisibilityWeight(other)});
      }
    }
  }
  return g;
}

double MedianSceneDepth(const Map& map, const KeyFrame& kf) {
  const SE3 cam_from_world = kf.cam_from_world();
  std::vector<double> depths;
  for (const MapPointId id : kf.map_points()) {
    if (!id.valid()) continue;
    if (const auto mp = map.map_point(id); mp && !mp->bad()) depths.push_back((cam_from_world * mp->position()).z());
  }
  if (depths.empty()) return 0.0;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  return depths[depths.size() / 2];
}

KeyframeId SpanningTreeAncestor(const Map& map, KeyframeId id, const std::function<bool(KeyframeId)>& accept,
                                int max_hops) {
  for (int hop = 0; hop <= max_hops && id.valid(); ++hop) {
    if (accept(id)) return id;
    const auto kf = map.keyframe(id);
    if (!kf) return KeyframeId::Invalid();
    id = kf->parent();
  }
  return KeyframeId::Invalid();
}

}  // namespace ccm
