// Registration of one agent's data into its server map (CCM-SLAM 4.5, Forster et al. III):
// a keyframe is placed with its pose relative to its predecessor (its covisibility parent if
// the predecessor never arrived, its VO pose through the handler's Sim(3) if neither did),
// the relative translation scaled by the handler's lambda; then refined against the map
// points it observes (reprojection), which also yields a new lambda sample. Map points are
// placed relative to their reference keyframe (they wait if it has not arrived); pose and
// position updates are applied the same way while the server has not corrected the data.
// One instance per agent (it holds the agent's waiting points), called by that agent's
// handler thread only; the map is shared with other handlers (per-object locks, structure
// lock shared).
#pragma once

#include <deque>
#include <map>
#include <memory>
#include <unordered_map>
#include <vector>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/server/map_stack.h"
#include "slam_core/server/server_options.h"

namespace ccm {

/// A server map locked shared for local edits; re-resolved if it was fused meanwhile.
struct SharedMapLock {
  std::shared_ptr<ServerMap> map;
  std::shared_lock<WriterPreferringMutex> lock;
};
SharedMapLock LockHandlerMap(MapStack* stack, AgentId agent, MapId segment, bool* created = nullptr);

struct RegisteredKeyframe {
  KeyframeId id;
  MapId map;
  enum class Placement { kPredecessor, kParent, kSegmentPose, kFirstOfMap } placement;
  bool refined = false;
  /// Registered before its own points arrived (KeyframeData::points_incomplete): server
  /// mapping and place recognition wait until they have (RegistrationReport::completed).
  bool deferred = false;
};

struct RegistrationReport {
  std::vector<RegisteredKeyframe> keyframes;  ///< newly in a map, in order
  /// Deferred keyframes (of this or earlier batches) whose points have come since, or that
  /// waited kMaxDeferredBatches: due for server mapping and place recognition now.
  std::vector<KeyframeId> completed;
  std::vector<KeyframeId> acked_keyframes;    ///< processed (new or already known): acknowledge
  std::vector<MapPointId> acked_points;
  std::vector<MapId> new_maps;                ///< maps created for new segments
  int points_registered = 0;
  int points_waiting = 0;                     ///< still waiting for their reference keyframe
  int points_dropped = 0;                     ///< waiting list overflow or no observer left
  int anchors_registered = 0;                 ///< anchor-only keyframes kept as anchors
  int anchors_dropped = 0;                    ///< anchor-only keyframes with nothing to hang on
  int kept_on_track = 0;                      ///< failed refinements redone on the predecessor's points
  int implausible_refinements = 0;            ///< refined poses that pulled too far: placement kept or redone
  int keyframe_updates_applied = 0;
  int point_updates_applied = 0;
  int updates_ignored = 0;                    ///< unknown ids, or data the server corrected since
};

class AgentRegistration {
 public:
  AgentRegistration(AgentId agent, MapStack* stack, const RegistrationOptions& options);

  /// Registers everything in `batch` (which must belong to this agent and be validated).
  RegistrationReport Register(const AgentBatch& batch);

  AgentId agent() const { return agent_; }
  size_t points_waiting() const;

 private:
  void RegisterKeyframe(const KeyframeData& kf, RegistrationReport* report);
  void RegisterAnchor(const KeyframeData& kf, double scale, ServerMap* map, RegistrationReport* report);
  void RegisterPoint(const MapPointData& mp, RegistrationReport* report);
  void ReleaseWaitingPoints(KeyframeId kf, RegistrationReport* report);
  void AddPendingLink(MapPointId mp, KeyframeId kf, int keypoint);
  /// `continuity`: the keyframe it was placed from (predecessor or parent; invalid if none).
  bool RefinePose(ServerMap* map, KeyFrame* kf, KeyframeId continuity, int* inliers, bool* kept_on_track,
                  bool* implausible);
  /// A keyframe placed without refinement keeps only the links that agree with its pose.
  static void DropLinksAgainstPose(Map* map, const KeyFrame& kf);
  void UpdateScale(const AgentHandler& handler, const KeyframeData& data, ServerMap* map, const KeyFrame& kf);
  void ApplyKeyframeUpdate(const KeyframePoseUpdate& u, RegistrationReport* report);
  void ApplyPointUpdate(const MapPointPositionUpdate& u, MapId segment, RegistrationReport* report);
  std::shared_ptr<const ScalePyramid> Pyramid(int levels, double factor);

  const AgentId agent_;
  MapStack* stack_;
  const RegistrationOptions options_;
  std::map<std::pair<int, double>, std::shared_ptr<const ScalePyramid>> pyramids_;
  /// Points whose reference keyframe has not arrived, by that keyframe.
  std::unordered_map<KeyframeId, std::vector<MapPointData>> waiting_;
  size_t num_waiting_ = 0;
  /// Links of registered keyframes to own points not here yet: attached when the point
  /// arrives (its message leaves such observations out). Oldest dropped beyond the cap
  /// (links to points the agent culled before sending them never resolve).
  std::unordered_map<MapPointId, std::vector<std::pair<KeyframeId, int>>> pending_links_;
  std::deque<MapPointId> pending_order_;
  /// Deferred keyframes: how many own points they waited for at registration, how many of
  /// those came since, and for how many batches. Complete at half (links to points the
  /// agent culled before sending them never resolve).
  struct Deferred {
    int pending = 0, resolved = 0, batches = 0;
  };
  static constexpr int kMaxDeferredBatches = 400;
  std::map<KeyframeId, Deferred> deferred_;
};

/// t scaled by `scale` (rotation kept): a VO relative pose in map units.
inline SE3 ScaledPose(const SE3& T, double scale) { return SE3(T.rotation(), T.translation() * scale); }

}  // namespace ccm
