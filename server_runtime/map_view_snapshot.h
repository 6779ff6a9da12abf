// The map view's picture of the server (issue 14): immutable, versioned snapshots of the
// back-end that the HTTP handlers read, so serving a page never touches a map lock.
// MapViewModel::Refresh() (one thread: the map view's snapshot thread) copies keyframe
// poses, decimated map points, covisibility edges, agents, events and the host's status
// out of the back-end through its thread-safe readers: no structure lock is taken (a loop
// correction or fusion never waits for the view), only the Map's table lock (shared) and
// the per-object locks, each for one bounded copy; the longest such hold is measured and
// reported. Every element remembers the version in which it last changed, and removals
// leave tombstones, so a client that has version N asks for what changed since N and the
// update cost stays flat as the map grows.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "slam_core/server/server_backend.h"

namespace ccm::server {

struct MapViewOptions {
  /// Map points kept in the snapshot at most: a stable, id-hashed subset (every 2^k-th)
  /// once the maps hold more. [count]
  size_t max_points = 60000;
  /// A keyframe or point counts as changed when it moved more than this [m].
  double min_change_m = 0.002;
  /// A removal is remembered this many versions; a client further behind reloads in full.
  uint64_t tombstone_versions = 2000;
  std::string Validate() const;
};

/// What the host (ccm_server, ccm_replay) adds to the status: per-agent link facts such as
/// tracking state and heartbeats, traffic, anything its own. Called from the snapshot thread.
/// Expected shape: {"agents": {"<id>": {...}}, ...}; "agents" entries are merged per agent.
using HostStatusFn = std::function<nlohmann::json()>;

struct ViewKeyframe {
  uint64_t id = 0, map = 0;
  float pose[7] = {0, 0, 0, 0, 0, 0, 1};  ///< world_from_cam in its map: x y z qx qy qz qw
  uint64_t changed = 0;                   ///< version of the last change
};

struct ViewPoint {
  uint64_t id = 0, map = 0;
  float xyz[3] = {0, 0, 0};
  uint64_t changed = 0;
};

struct ViewEdge {
  uint64_t a = 0, b = 0;  ///< keyframe ids, a < b
  int weight = 0;
  uint64_t changed = 0;
};

/// A removed element, remembered so that clients behind get told.
struct Tombstone {
  uint64_t id = 0;       ///< keyframe or point id; an edge's first keyframe
  uint64_t b = 0;        ///< an edge's second keyframe (0 otherwise)
  uint64_t version = 0;  ///< removed in this version
};

/// One refresh's timing, for the status and docs/map-view.md.
struct SnapshotTiming {
  double refresh_ms = 0.0;          ///< the whole Refresh()
  double max_lock_hold_us = 0.0;    ///< longest single call that holds a back-end lock
  double max_lock_hold_us_ever = 0.0;
  int64_t refreshes = 0;
};

struct MapViewSnapshot {
  uint64_t version = 0;             ///< increases whenever anything in the map changed
  uint64_t oldest_tombstone = 0;    ///< a client with since < this must reload in full
  double server_time_s = 0.0;       ///< when taken, seconds since the view started
  std::vector<ViewKeyframe> keyframes;  ///< sorted by id
  std::vector<ViewPoint> points;        ///< sorted by id (decimated)
  size_t point_stride = 1;              ///< 1 of every `point_stride` points is kept
  std::vector<ViewEdge> edges;          ///< sorted by (a, b)
  std::vector<Tombstone> removed_keyframes, removed_points, removed_edges;  ///< by version
  nlohmann::json status;                ///< agents, maps, totals, queues, host facts
  std::vector<ServerEvent> events;      ///< every event so far, in order
  SnapshotTiming timing;
};

/// Builds the snapshots. Owned by MapViewServer; Refresh() from one thread at a time,
/// Latest() from any thread.
class MapViewModel {
 public:
  MapViewModel(const ServerBackend* backend, MapViewOptions options, HostStatusFn host_status = {});
  /// Copies the back-end's state into a new snapshot (diffed against the previous one).
  void Refresh();
  std::shared_ptr<const MapViewSnapshot> Latest() const;
  /// The status part alone, taken now (no map copy): what /metrics renders, so a scrape
  /// never reads a snapshot the idle view stopped refreshing.
  nlohmann::json CurrentStatus();

 private:
  void CopyMaps(const MapStackSnapshot& stack, MapViewSnapshot* next, double* max_hold_us);
  void BuildStatus(const MapStackSnapshot& stack, MapViewSnapshot* next, double* max_hold_us);
  void Diff(const MapViewSnapshot& prev, MapViewSnapshot* next, bool* changed) const;

  const ServerBackend* backend_;
  const MapViewOptions options_;
  HostStatusFn host_status_;
  const std::chrono::steady_clock::time_point start_;
  mutable std::mutex mutex_;  // guards latest_ (a pointer swap); leaf
  std::shared_ptr<const MapViewSnapshot> latest_;
};

/// Id text as the API shows it: "agent:counter" (64-bit ids do not fit a JavaScript number).
std::string IdText(uint64_t packed);

}  // namespace ccm::server
