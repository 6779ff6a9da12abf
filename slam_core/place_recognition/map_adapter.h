// Glue between ccm_map and place recognition: snapshots a KeyFrame of a Map into the value
// types the database and the verifier take, and exposes a map's covisibility graph as a
// CovisibilityFn. Reads the map through its thread-safe accessors (per-object locks held
// only inside each call), so any thread may use these while the map is being edited; the
// snapshot is then a consistent-enough copy, as ORB-SLAM's loop closer sees.
#pragma once

#include "slam_core/map/keyframe.h"
#include "slam_core/map/map.h"
#include "slam_core/place_recognition/geometric_verification.h"
#include "slam_core/place_recognition/keyframe_database.h"
#include "slam_core/place_recognition/vocabulary.h"

namespace ccm {

/// Verification input for `kf`: its features, camera and pyramid, its good map points moved
/// into its camera frame, and the direct index from `vocab` (levels_up as in Transform).
/// `bow` (optional) receives the keyframe's bag of words from the same pass.
VerificationView MakeVerificationView(const KeyFrame& kf, const Map& map, const Vocabulary& vocab,
                                      int levels_up = 4, BowVector* bow = nullptr);

/// Best covisible keyframes from `map` (empty for unknown keyframes). The map must outlive
/// the returned function.
CovisibilityFn MapCovisibility(const Map& map);

}  // namespace ccm
