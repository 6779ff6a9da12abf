#include "server_runtime/map_view_snapshot.h"

#include <algorithm>
#include <cmath>

namespace ccm::server {
namespace {

using Clock = std::chrono::steady_clock;

/// Runs `f` and raises *max_us to its duration: used around every call that holds a
/// back-end lock while it copies (the lock is released when the call returns).
template <typename F>
auto Timed(double* max_us, F&& f) {
  const auto t0 = Clock::now();
  auto result = f();
  *max_us = std::max(*max_us, std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  return result;
}

/// Stable pseudo-random bits of an id (splitmix64 finalizer): decimation keeps the same
/// points from one snapshot to the next.
uint64_t Mix(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

bool KeyframeMoved(const ViewKeyframe& a, const ViewKeyframe& b, double min_m) {
  if (a.map != b.map) return true;
  const double dx = a.pose[0] - b.pose[0], dy = a.pose[1] - b.pose[1], dz = a.pose[2] - b.pose[2];
  if (dx * dx + dy * dy + dz * dz > min_m * min_m) return true;
  const double dot = a.pose[3] * b.pose[3] + a.pose[4] * b.pose[4] + a.pose[5] * b.pose[5] + a.pose[6] * b.pose[6];
  return std::abs(dot) < 1.0 - 1e-6;  // about 0.16 degrees
}

bool PointMoved(const ViewPoint& a, const ViewPoint& b, double min_m) {
  if (a.map != b.map) return true;
  const double dx = a.xyz[0] - b.xyz[0], dy = a.xyz[1] - b.xyz[1], dz = a.xyz[2] - b.xyz[2];
  return dx * dx + dy * dy + dz * dz > min_m * min_m;
}

/// Merge-joins two id-sorted lists: elements kept from `prev` keep their value and version
/// unless `moved`, new ones get `version`, vanished ones become tombstones.
template <typename T, typename Key, typename Moved>
bool DiffSorted(const std::vector<T>& prev, std::vector<T>* next, uint64_t version, Key key, Moved moved,
                std::vector<Tombstone>* removed) {
  bool changed = false;
  size_t i = 0;
  for (T& n : *next) {
    while (i < prev.size() && key(prev[i]) < key(n)) {
      removed->push_back({key(prev[i]).first, key(prev[i]).second, version});
      changed = true;
      ++i;
    }
    if (i < prev.size() && key(prev[i]) == key(n)) {
      // Below the threshold the element keeps the value clients already have, so a slow
      // drift is measured from what was last sent and goes out once it adds up.
      if (moved(prev[i], n)) {
        n.changed = version;
      } else {
        n = prev[i];
      }
      ++i;
    } else {
      n.changed = version;
    }
    changed |= n.changed == version;
  }
  for (; i < prev.size(); ++i) {
    removed->push_back({key(prev[i]).first, key(prev[i]).second, version});
    changed = true;
  }
  return changed;
}

void Prune(std::vector<Tombstone>* t, uint64_t horizon) {
  t->erase(std::remove_if(t->begin(), t->end(), [horizon](const Tombstone& x) { return x.version < horizon; }),
           t->end());
}

}  // namespace

std::string MapViewOptions::Validate() const {
  if (max_points < 1 || max_points > 2000000) return "map view: max_points must be in 1..2000000";
  if (!(min_change_m >= 0.0)) return "map view: min_change_m must be >= 0";
  if (tombstone_versions < 1) return "map view: tombstone_versions must be >= 1";
  return "";
}

std::string IdText(uint64_t packed) {
  const KeyframeId id(packed);
  return std::to_string(id.agent()) + ":" + std::to_string(id.counter());
}

MapViewModel::MapViewModel(const ServerBackend* backend, MapViewOptions options, HostStatusFn host_status)
    : backend_(backend), options_(options), host_status_(std::move(host_status)), start_(Clock::now()),
      latest_(std::make_shared<MapViewSnapshot>()) {}

std::shared_ptr<const MapViewSnapshot> MapViewModel::Latest() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return latest_;
}

void MapViewModel::CopyMaps(const MapStackSnapshot& stack, MapViewSnapshot* next, double* max_hold_us) {
  const auto& maps = stack.maps;
  std::vector<std::vector<std::shared_ptr<MapPoint>>> points(maps.size());
  size_t total_points = 0;
  for (size_t m = 0; m < maps.size(); ++m) {
    const Map& map = maps[m]->map();
    const uint64_t map_id = maps[m]->id().packed();
    const auto kfs = Timed(max_hold_us, [&] { return map.keyframes(); });
    for (const auto& kf : kfs) {
      const SE3 pose = Timed(max_hold_us, [&] { return kf->world_from_cam(); });
      ViewKeyframe v;
      v.id = kf->id().packed();
      v.map = map_id;
      const Eigen::Vector3d t = pose.translation();
      const Eigen::Quaterniond q = pose.rotation();
      const double p[7] = {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
      std::copy(p, p + 7, v.pose);
      next->keyframes.push_back(v);
      const auto covis = Timed(max_hold_us, [&] { return kf->covisibility(); });
      for (const auto& [other, weight] : covis) {
        if (kf->id() < other) next->edges.push_back({kf->id().packed(), other.packed(), weight, 0});
      }
    }
    points[m] = Timed(max_hold_us, [&] { return map.map_points(); });
    total_points += points[m].size();
  }
  size_t stride = 1;
  while (total_points / stride > options_.max_points) stride *= 2;
  next->point_stride = stride;
  for (size_t m = 0; m < maps.size(); ++m) {
    for (const auto& mp : points[m]) {
      if (stride > 1 && Mix(mp->id().packed()) % stride != 0) continue;
      // One point's own mutex for a 3-vector copy: bounded, not timed one by one.
      const Eigen::Vector3d x = mp->position();
      next->points.push_back({mp->id().packed(), maps[m]->id().packed(),
                              {static_cast<float>(x.x()), static_cast<float>(x.y()), static_cast<float>(x.z())}, 0});
    }
  }
  // A fusion adds the absorbed map's keyframes and points to the kept map before it drops
  // the absorbed one, so for a moment both list them. Each id must appear once: a duplicate
  // left over in the previous snapshot would be diffed as a removal of an id still present,
  // and a client would drop it for good. Which copy stays does not matter: the absorbed map
  // leaves the stack right after, and a changed map id goes out as a change.
  auto sort_unique = [](auto* list, auto less, auto same) {
    std::sort(list->begin(), list->end(), less);
    list->erase(std::unique(list->begin(), list->end(), same), list->end());
  };
  auto by_id = [](const auto& a, const auto& b) { return a.id < b.id; };
  auto same_id = [](const auto& a, const auto& b) { return a.id == b.id; };
  sort_unique(&next->keyframes, by_id, same_id);
  sort_unique(&next->points, by_id, same_id);
  sort_unique(
      &next->edges, [](const ViewEdge& a, const ViewEdge& b) { return a.a != b.a ? a.a < b.a : a.b < b.b; },
      [](const ViewEdge& a, const ViewEdge& b) { return a.a == b.a && a.b == b.b; });
}

void MapViewModel::Diff(const MapViewSnapshot& prev, MapViewSnapshot* next, bool* changed) const {
  const uint64_t v = next->version;
  const double min_m = options_.min_change_m;
  *changed = false;
  *changed |= DiffSorted(
      prev.keyframes, &next->keyframes, v, [](const ViewKeyframe& k) { return std::make_pair(k.id, uint64_t{0}); },
      [min_m](const ViewKeyframe& a, const ViewKeyframe& b) { return KeyframeMoved(a, b, min_m); },
      &next->removed_keyframes);
  *changed |= DiffSorted(
      prev.points, &next->points, v, [](const ViewPoint& p) { return std::make_pair(p.id, uint64_t{0}); },
      [min_m](const ViewPoint& a, const ViewPoint& b) { return PointMoved(a, b, min_m); }, &next->removed_points);
  *changed |= DiffSorted(
      prev.edges, &next->edges, v, [](const ViewEdge& e) { return std::make_pair(e.a, e.b); },
      [](const ViewEdge& a, const ViewEdge& b) { return a.weight != b.weight; }, &next->removed_edges);
}

nlohmann::json MapViewModel::CurrentStatus() {
  MapViewSnapshot next;
  double max_hold_us = 0.0;
  const MapStackSnapshot stack = backend_->Snapshot();
  next.events = stack.events;
  BuildStatus(stack, &next, &max_hold_us);
  next.status["server_time_s"] = std::chrono::duration<double>(Clock::now() - start_).count();
  return next.status;
}

void MapViewModel::Refresh() {
  const auto t0 = Clock::now();
  const auto prev = Latest();
  auto next = std::make_shared<MapViewSnapshot>();
  double max_hold_us = 0.0;
  const MapStackSnapshot stack = Timed(&max_hold_us, [&] { return backend_->Snapshot(); });
  CopyMaps(stack, next.get(), &max_hold_us);
  next->removed_keyframes = prev->removed_keyframes;
  next->removed_points = prev->removed_points;
  next->removed_edges = prev->removed_edges;
  next->version = prev->version + 1;
  bool changed = false;
  Diff(*prev, next.get(), &changed);
  if (!changed) {
    // Nothing moved: keep the version, so polling clients get empty answers.
    next->version = prev->version;
  }
  const uint64_t horizon = next->version > options_.tombstone_versions ? next->version - options_.tombstone_versions : 0;
  Prune(&next->removed_keyframes, horizon);
  Prune(&next->removed_points, horizon);
  Prune(&next->removed_edges, horizon);
  next->oldest_tombstone = horizon;
  next->events = stack.events;
  BuildStatus(stack, next.get(), &max_hold_us);
  next->server_time_s = std::chrono::duration<double>(Clock::now() - start_).count();
  next->timing.refresh_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  next->timing.max_lock_hold_us = max_hold_us;
  next->timing.max_lock_hold_us_ever = std::max(prev->timing.max_lock_hold_us_ever, max_hold_us);
  next->timing.refreshes = prev->timing.refreshes + 1;
  std::lock_guard<std::mutex> lock(mutex_);
  latest_ = std::move(next);
}

}  // namespace ccm::server
