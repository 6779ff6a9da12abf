// Glue between ccm_map and place recognition: snapshots a KeyFrame of a Map into the value
// types the database and the verifier take, and exposes a map's covisibility graph as a
// CovisibilityFn. Reads the map through its thread-safe accessors (per-object locks held
// only inside each call), so any thread may use these while the map is being edited; the
// snapshot is then a consistent-enough copy, as ORB-SLAM's loop closer sees.
#pragma once

#include <functional>
#include <memory>
#include <vector>

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

/// Per keypoint of a keyframe, its vocabulary node at the direct-index depth
/// (NodesOfFeatures): a caller that keeps them from the keyframe's query spares the
/// vocabulary descent for every verification.
using KeypointNodesFn = std::function<std::vector<NodeId>(const KeyFrame&)>;
/// Computes them with `vocab` each time (levels_up as in Vocabulary::Transform).
KeypointNodesFn VocabularyNodes(const Vocabulary& vocab, int levels_up);

/// Verification input for `kf` and the place around it (ORB-SLAM3's merge window): the view
/// of `kf` followed by one extra feature per good map point that a keyframe of `neighbours`
/// sees, `kf` does not, and that projects into `kf`'s image (keypoint at that projection,
/// the neighbour's descriptor, level moved by the depth ratio). A query seen from another
/// height or angle than `kf` finds more of its points in the window than in `kf` alone, so
/// brief and oblique overlaps pass the BoW stage. Indices >= kf's keypoint count are the
/// extra features (`real_keypoints` receives that count). No neighbours: `kf`'s own view.
VerificationView MakeWindowView(const KeyFrame& kf, const std::vector<std::shared_ptr<KeyFrame>>& neighbours,
                                const Map& map, const KeypointNodesFn& nodes, size_t* real_keypoints);

/// Best covisible keyframes from `map` (empty for unknown keyframes). The map must outlive
/// the returned function.
CovisibilityFn MapCovisibility(const Map& map);

}  // namespace ccm
