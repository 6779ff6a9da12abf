// A map: keyframes and map points indexed by id, with the covisibility graph, the
// spanning tree and loop edges kept consistent on every edit. Used by the agent's
// local map and by each server map (several agent handlers may write after a fusion).
//
// Concurrency (see docs/architecture.md, "Map locking"):
//  * graph_mutex_ serializes topology edits (connections, erasure, replacement, loops);
//  * tables_mutex_ (reader/writer) guards only the id tables and is never held while an
//    object is called;
//  * each KeyFrame / MapPoint has its own mutex held only inside its methods, so pose and
//    association updates of different keyframes run in parallel (per-keyframe locking).
//  Lock order: graph_mutex_ -> tables_mutex_ -> one object mutex. Never two object mutexes.
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "slam_core/map/keyframe.h"
#include "slam_core/map/map_point.h"

namespace ccm {

struct MapOptions {
  int covisibility_min_shared = 15;  ///< shared map points for a covisibility edge [count]
  int essential_min_weight = 100;    ///< covisibility weight that enters the essential graph
  std::string Validate() const;
};

/// Value snapshot of the essential graph (input to pose-graph optimization).
struct EssentialGraph {
  enum class EdgeType { kSpanningTree, kCovisibility, kLoop };
  struct Edge {
    KeyframeId a, b;
    EdgeType type;
    int weight;  ///< shared map points (0 for loop edges without covisibility)
  };
  std::vector<KeyframeId> nodes;  ///< sorted by id
  std::vector<Edge> edges;        ///< each undirected edge once
};

class Map {
 public:
  explicit Map(MapId id, MapOptions options = {});
  MapId id() const { return id_; }
  const MapOptions& options() const { return options_; }

  bool AddKeyframe(std::shared_ptr<KeyFrame> kf);  ///< false if the id exists
  bool AddMapPoint(std::shared_ptr<MapPoint> mp);  ///< false if the id exists
  std::shared_ptr<KeyFrame> keyframe(KeyframeId id) const;  ///< nullptr if absent
  std::shared_ptr<MapPoint> map_point(MapPointId id) const;
  /// map_point() of each id under one lock (nullptr where absent), in the order given.
  std::vector<std::shared_ptr<MapPoint>> map_points(const std::vector<MapPointId>& ids) const;
  std::vector<std::shared_ptr<KeyFrame>> keyframes() const;  ///< sorted by id
  std::vector<std::shared_ptr<MapPoint>> map_points() const;  ///< sorted by id
  size_t num_keyframes() const;
  size_t num_map_points() const;

  /// Associates keypoint `keypoint` of `kf` with `mp` on both sides. False if either is
  /// missing, the keypoint index is out of range or already holds another point.
  bool AddObservation(KeyframeId kf, int keypoint, MapPointId mp);
  /// Removes the association on both sides; a point left without observations is erased.
  void EraseObservation(KeyframeId kf, MapPointId mp);

  /// Recomputes the covisibility edges of `kf` (both directions) from shared points and
  /// gives it a spanning-tree parent (strongest neighbour) if it has none yet.
  void UpdateConnections(KeyframeId kf);
  void AddLoopEdge(KeyframeId a, KeyframeId b);
  /// Removes a keyframe: detaches its observations (erasing orphaned points), removes its
  /// covisibility edges and re-parents its children so the spanning tree stays a tree.
  bool EraseKeyframe(KeyframeId kf);
  bool EraseMapPoint(MapPointId mp);
  /// Fuses duplicate `old_mp` into `keep`: observations move, `old_mp` is marked replaced.
  bool ReplaceMapPoint(MapPointId old_mp, MapPointId keep);
  /// Recomputes descriptor (smallest median distance), mean viewing normal and the depth
  /// range in which the point can be matched.
  void UpdateMapPointAppearance(MapPointId mp);

  EssentialGraph BuildEssentialGraph() const;

 private:
  void ReparentChildren(const std::shared_ptr<KeyFrame>& erased);
  void EraseMapPointLocked(const std::shared_ptr<MapPoint>& mp);

  const MapId id_;
  const MapOptions options_;
  mutable std::mutex graph_mutex_;
  mutable std::shared_mutex tables_mutex_;
  std::unordered_map<KeyframeId, std::shared_ptr<KeyFrame>> keyframes_;
  std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> map_points_;
};

/// Median depth of the good points `kf` observes, in its camera frame; 0 if it sees none.
double MedianSceneDepth(const Map& map, const KeyFrame& kf);

/// The nearest of `id` and its spanning-tree ancestors that `accept` takes (a keyframe added
/// after a snapshot follows the correction of the newest one that was in it); invalid if
/// none within `max_hops` or the chain leaves the map.
KeyframeId SpanningTreeAncestor(const Map& map, KeyframeId id, const std::function<bool(KeyframeId)>& accept,
                                int max_hops = 256);

}  // namespace ccm
