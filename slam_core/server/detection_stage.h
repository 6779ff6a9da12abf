// Detection handling, the stage after place recognition: a verified detection becomes a
// closed loop (one map) or a fusion (two maps become one), reported as a ServerEvent. What
// has to follow (a global BA of the changed map, forgetting the absorbed map's pending one)
// is returned for the scheduler; the stage owns no thread and no queue. Synchronous: runs
// on the place-recognition thread, taking the maps' structure locks as CloseLoop and
// FuseMaps document.
#pragma once

#include <functional>
#include <optional>
#include <string>

#include "slam_core/server/map_stack.h"
#include "slam_core/server/place_matcher.h"
#include "slam_core/server/server_event.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct DetectionOutcome {
  std::optional<ServerEvent> event;  ///< set when a loop closed or two maps fused
  MapId optimize;                    ///< global BA wanted next (invalid: none)
  MapId forget;                      ///< the absorbed map: a global BA pending for it is moot
  std::string refused;               ///< without an event: why the loop or fusion did not happen
};

class DetectionStage {
 public:
  /// Place recognition's database follows the maps: told of every closed loop and fusion
  /// while the maps involved are still locked (fusion) or right after (loop).
  struct Hooks {
    std::function<void(MapId map)> loop_closed;
    std::function<void(MapId absorbed, MapId kept)> maps_fused;
  };

  DetectionStage(MapStack* stack, const ServerOptions& options, Hooks hooks);

  /// `time_s`: the event's time (seconds since the back-end started).
  DetectionOutcome Handle(const PlaceDetection& detection, double time_s) const;

 private:
  DetectionOutcome CloseLoopOf(const PlaceDetection& d, ServerEvent e) const;
  DetectionOutcome FuseMapsOf(const PlaceDetection& d, ServerEvent e) const;

  MapStack* stack_;
  const ServerOptions& options_;
  Hooks hooks_;
};

}  // namespace ccm
