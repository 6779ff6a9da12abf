// Loop closure inside one server map (CCM-SLAM 4.7, ORB-SLAM's CorrectLoop): the query
// keyframe and its covisible neighbourhood are moved to where the verified Sim(3) puts them,
// their points with them; the candidate side's points are fused into the corrected
// neighbourhood; the essential graph is optimized with the new loop connections; every
// keyframe and point of the map takes the correction. A global BA follows (the caller
// schedules it). Synchronous. Takes the map's structure lock exclusively to move the
// neighbourhood and build the pose graph, releases it while the pose graph is solved, and
// takes it again to apply the result: the caller must keep global BAs of the map from
// starting until CloseLoop returns (BackendScheduler::HoldGlobalBaOf).
#pragma once

#include "slam_core/server/map_stack.h"
#include "slam_core/server/place_matcher.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct LoopReport {
  bool closed = false;
  std::string reason;  ///< why not, if not closed
  MapId map;
  KeyframeId query, candidate;
  int neighbourhood = 0;       ///< keyframes moved with the query before the pose graph
  int points_fused = 0;
  int loop_connections = 0;
  double correction_m = 0.0;   ///< how far the query keyframe moved
  double correction_deg = 0.0;
  double scale_correction = 1.0;
  int keyframes_added_meanwhile = 0;  ///< registered while the pose graph was solved
  double pose_graph_s = 0.0;
  double locked_s = 0.0;              ///< time the map's structure lock was held exclusively
  double seconds = 0.0;
};

/// Closes the loop of `detection` (kind kLoop). Handlers of the map get their scale factor
/// corrected with the scale change at their newest keyframe.
LoopReport CloseLoop(MapStack* stack, const PlaceDetection& detection, const ServerOptions& options);

}  // namespace ccm
