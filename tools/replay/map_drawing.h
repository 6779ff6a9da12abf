// The fused map as files: an ASCII PLY (map points grey, keyframe centres coloured per agent)
// and a PNG top view (points, each agent's keyframe trajectory, ground truth when known),
// drawn in the ground-truth frame when the replay was scored, else in the map frame on its
// two principal axes.
#pragma once

#include <string>

#include "tools/replay/replay_report.h"

namespace ccm::replay {

bool WriteMapPly(const std::string& path, const ServerBackend& backend, MapId map, std::string* error);
bool WriteMapTopView(const std::string& path, const ReplayResult& result, const ReplayEvaluation& evaluation,
                     const ServerBackend& backend, std::string* error, int size_px = 1200);

}  // namespace ccm::replay
