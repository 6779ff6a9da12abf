// One map of the server's map stack: a ccm::Map plus what the server knows beyond it
// (per-keyframe registration facts, anchors of keyframes that are not in the map, merged
// point ids) and the structure lock that separates local edits from whole-map edits.
// Shared by the map stack, every handler registering into it and the optimization jobs.
//
// Locking (docs/server.md):
//  * structure_mutex(): shared for local edits that the Map's own per-object locks make safe
//    (registration, server mapping, redundancy removal, snapshots for global BA); exclusive
//    for edits of the whole map (loop correction, fusion, global BA write-back).
//  * tables_mutex_ guards the side tables only; it is a leaf (nothing is called while held).
//  Lock order: MapStack (leaf, never held across calls) ; structure mutexes of two maps in
//  ascending map id ; Map internals ; KeyframeDatabase (leaf) ; tables_mutex_ (leaf).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include "slam_core/common/writer_preferring_mutex.h"
#include "slam_core/geometry/se3.h"
#include "slam_core/map/map.h"

namespace ccm {

/// What the server keeps about a registered keyframe besides the Map's data.
struct ServerKeyframeInfo {
  MapId segment;            ///< the agent's VO segment it came from
  KeyframeId predecessor;   ///< as received
  KeyframeId parent;
  SE3 pred_from_cam;        ///< as received, VO scale (updates replace it)
  SE3 parent_from_cam;
  SE3 segment_from_cam;     ///< the agent's VO pose when sent
  /// Set once the server optimized the keyframe with information of its own (local BA, loop
  /// correction, global BA): from then on the server's estimate wins over the agent's later
  /// local-BA updates, which carry no observation the server does not have. Until then those
  /// updates are the best pose there is, for the keyframe and the points it references. The
  /// pose-only refinement at registration does not settle: it sees only the agent's own
  /// links, and freezing its result dropped every later update (the server's map of an agent
  /// then bent away from the agent's VO before any loop).
  bool settled = false;
};

/// A keyframe that is not in the map (skipped as a near-duplicate or removed as redundant):
/// its pose relative to a keyframe that was in the map when it was anchored. Relative, so it
/// follows every later correction and fusion of its base.
struct KeyframeAnchor {
  KeyframeId base;
  SE3 base_from_cam;
  int64_t stamp_ns = 0;
  MapId segment;
};

class ServerMap {
 public:
  ServerMap(MapId id, const MapOptions& options) : id_(id), map_(id, options) {}
  ServerMap(const ServerMap&) = delete;
  ServerMap& operator=(const ServerMap&) = delete;

  MapId id() const { return id_; }
  Map& map() { return map_; }
  const Map& map() const { return map_; }
  WriterPreferringMutex& structure_mutex() const { return structure_mutex_; }

  /// Incremented by every whole-map edit (loop, fusion, global BA write-back): a global BA
  /// whose snapshot is of an older generation must not write back.
  uint64_t generation() const { return generation_.load(); }
  void BumpGeneration() { ++generation_; }
  /// Loading a saved map: continue its counter (a snapshot taken before the save never
  /// writes back into the loaded map).
  void RestoreGeneration(uint64_t generation) { generation_ = generation; }

  /// Set (under the exclusive lock) when this map was fused into another; handlers that
  /// still hold it re-resolve their map.
  bool retired() const { return retired_.load(); }
  void Retire() { retired_ = true; }

  void SetInfo(KeyframeId id, const ServerKeyframeInfo& info);
  std::optional<ServerKeyframeInfo> Info(KeyframeId id) const;
  void MarkSettled(const std::vector<KeyframeId>& ids);
  void EraseInfo(KeyframeId id);

  void AddAnchor(KeyframeId id, const KeyframeAnchor& anchor);
  std::optional<KeyframeAnchor> Anchor(KeyframeId id) const;
  std::unordered_map<KeyframeId, KeyframeAnchor> anchors() const;
  /// Pose of a keyframe in this map, following anchors to a keyframe in the map.
  std::optional<SE3> PoseOf(KeyframeId id) const;
  /// Where the chain of anchors starting at `id` ends: `id` itself if it is not anchored,
  /// else the first base that is not (normally a keyframe in the map).
  KeyframeId AnchorRoot(KeyframeId id) const;
  /// True if the keyframe is in the map or anchored to it.
  bool Knows(KeyframeId id) const;
  /// A Sim(3) correction (fusion, loop closure) changed the map's scale around some
  /// keyframes: an anchor's offset from its base is in map units and must follow, or it
  /// lands off by (scale - 1) x its offset (a fusion at scale 1.33 put anchors 10-20 cm
  /// off). `scale_of(root)`: the scale change at the keyframe in the map that the anchor's
  /// chain ends in (1: unchanged).
  void RescaleAnchors(const std::function<double(KeyframeId root)>& scale_of);

  /// A point merged into another: links that still name the old id resolve to the new one.
  void RecordReplacement(MapPointId old_id, MapPointId keep);
  MapPointId Resolve(MapPointId id) const;

  /// Moves the side tables of a map fused into this one (anchors stay relative).
  void AbsorbTables(ServerMap* other);
  /// Copies for persistence.
  std::unordered_map<KeyframeId, ServerKeyframeInfo> infos() const;
  std::unordered_map<MapPointId, MapPointId> replacements() const;

 private:
  const MapId id_;
  Map map_;
  mutable WriterPreferringMutex structure_mutex_;
  std::atomic<uint64_t> generation_{0};
  std::atomic<bool> retired_{false};

  mutable std::mutex tables_mutex_;
  std::unordered_map<KeyframeId, ServerKeyframeInfo> info_;
  std::unordered_map<KeyframeId, KeyframeAnchor> anchors_;
  std::unordered_map<MapPointId, MapPointId> replaced_;
};

}  // namespace ccm
