// How far the trajectories ran between two keyframes of one map: the path along which VO
// drift can have built up between them. The server bounds a loop correction by a share of
// it (an aliased place implies a correction far beyond any drift), also for loops between
// two agents of a fused map, which meet through the keyframes where their maps overlap
// (directly or through other agents).
#pragma once

#include <optional>

#include "slam_core/map/map.h"

namespace ccm {

/// Path length (map units) between keyframes `a` and `b` of `map`:
///  * same agent: through that agent's keyframes whose counters lie between the two (also
///    when one of the two has been removed meanwhile; 0 when none is left);
///  * different agents: the shortest route along the agents' trajectories that changes
///    agent only at junctions, i.e. keyframes of two agents covisible with
///    >= `min_shared_points` shared points. Two agents whose maps met only through a third
///    one are joined through its trajectory.
/// nullopt for two agents when either keyframe is not in the map or no chain of junctions
/// joins them (the junction keyframes were removed).
/// Locks the keyframes one at a time; the caller keeps the map's structure stable.
std::optional<double> DriftPath(const Map& map, KeyframeId a, KeyframeId b, int min_shared_points = 15);

}  // namespace ccm
