// Applies server data to the agent's local map: new keyframes/points are inserted (placed
// with the current pose of the agent's reference keyframe), known ones from other agents are
// moved to the server's estimate; the agent's own keyframes keep the VO's estimate. Runs on
// the local-mapping thread (AgentVo queues the data), so it never races the mapper.
#pragma once

#include "slam_core/map/map.h"
#include "slam_core/vo/local_map_bound.h"
#include "slam_core/exchange/server_map_data.h"

namespace ccm {

void IntegrateServerData(const ServerMapData& data, AgentId own_agent, const std::shared_ptr<const ScalePyramid>& pyramid,
                         Map* map, LocalMapBound* bound, ServerDataStats* stats);

}  // namespace ccm
