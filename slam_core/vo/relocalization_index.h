// Bag-of-words index over the agent's local map for relocalization (ORB-SLAM's keyframe
// database, CCM-SLAM's agent): a lost agent asks which keyframes look like its frame and
// matches only their points, instead of every point of the map.
//
// Threads: Sync() runs on the mapping thread (the only writer of `indexed_`); Candidates()
// on the tracking thread. The database is internally locked and never calls out while
// locked; Candidates() locks keyframes (covisibility) with no lock of its own held, so
// there is no lock-order constraint with the map.
#pragma once

#include <memory>
#include <unordered_set>
#include <vector>

#include "slam_core/map/map.h"
#include "slam_core/place_recognition/keyframe_database.h"
#include "slam_core/place_recognition/vocabulary.h"

namespace ccm {

class RelocalizationIndex {
 public:
  explicit RelocalizationIndex(std::shared_ptr<const Vocabulary> vocabulary);

  /// Mapping thread: indexes keyframes of `map` not indexed yet (own and the server's) and
  /// forgets those that left it (culled, trimmed, or a previous segment's). About 1 ms per
  /// new keyframe at 1000 features.
  void Sync(const Map& map);

  /// Tracking thread: keyframes of `map` whose covisibility group looks most like an image
  /// with these descriptors, best first, at most max_candidates.
  std::vector<std::shared_ptr<KeyFrame>> Candidates(const std::vector<OrbDescriptor>& descriptors,
                                                    const Map& map, int max_candidates) const;

  size_t size() const { return database_.size(); }

 private:
  const std::shared_ptr<const Vocabulary> vocabulary_;
  KeyframeDatabase database_;
  std::unordered_set<KeyframeId> indexed_;  // mapping thread only
};

}  // namespace ccm
