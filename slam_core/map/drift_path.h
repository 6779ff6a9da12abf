// How far the trajectories ran between two keyframes of one map: the path along which VO
// drift can have built up between them. The server bounds a loop correction by a share of
// it (an aliased place implies a correction far beyond any drift), also for loops between
// two agents of a fused map, which meet through the keyframes where their maps overlap.
#pragma once

#include <optional>

#include "slam_core/map/map.h"

namespace ccm {

/// Path length (map units) between keyframes `a` and `b` of `map`:
///  * same agent: through that agent's keyframes whose counters lie between the two (also
///    when one of the two has been removed meanwhile; 0 when none is left);
///  * different agents: the shortest route through a junction, i.e. a keyframe of a's agent
///    covisible (>= `min_shared_points` shared points) with one of b's agent: a's agent's
///    path from `a` to its side of the junction plus b's agent's path from the other side
///    to `b`.
/// nullopt for two agents when either keyframe is not in the map or they have no junction
/// (their maps met only through a third agent, or the junction keyframes were removed).
/// Locks the keyframes one at a time; the caller keeps the map's structure stable.
std::optional<double> DriftPath(const Map& map, KeyframeId a, KeyframeId b, int min_shared_points = 15);

}  // namespace ccm
