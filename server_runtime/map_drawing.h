// Server maps as files: an ASCII PLY per map (map points grey, keyframe centres coloured per
// agent) and one PNG top view with a panel per map, largest first (maps that never fused
// have unrelated frames, so each gets its own panel and scale bar). A panel is drawn in the
// ground-truth frame when its map was scored, else in the map frame; either way seen from
// above, "up" being opposite the cameras' mean image-down direction (level cameras: cars,
// drones with forward cameras, hand-held), or the flat axis of the keyframes otherwise.
#pragma once

#include <string>

#include "server_runtime/run_report.h"

namespace ccm::report {

bool WriteMapPly(const std::string& path, const MapStackSnapshot& maps, MapId map, std::string* error);
/// `panel_px`: side of each panel; 0: 1200 for one map, 800 for several.
bool WriteMapTopView(const std::string& path, const RunResult& result, const RunEvaluation& evaluation,
                     const MapStackSnapshot& maps, std::string* error, int panel_px = 0);

}  // namespace ccm::report
