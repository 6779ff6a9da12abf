#include "slam_core/vo/relocalization_index.h"

namespace ccm {

RelocalizationIndex::RelocalizationIndex(std::shared_ptr<const Vocabulary> vocabulary)
    : vocabulary_(std::move(vocabulary)), database_(vocabulary_->num_words()) {}

void RelocalizationIndex::Sync(const Map& map) {
  std::unordered_set<KeyframeId> present;
  for (const auto& kf : map.keyframes()) {
    if (kf->bad()) continue;
    present.insert(kf->id());
    if (indexed_.count(kf->id())) continue;
    BowVector bow;
    vocabulary_->Transform(kf->features().descriptors, &bow);
    database_.Add(kf->id(), map.id(), bow);
    indexed_.insert(kf->id());
  }
  for (auto it = indexed_.begin(); it != indexed_.end();) {
    if (present.count(*it)) {
      ++it;
    } else {
      database_.Erase(*it);
      it = indexed_.erase(it);
    }
  }
}

std::vector<std::shared_ptr<KeyFrame>> RelocalizationIndex::Candidates(
    const std::vector<OrbDescriptor>& descriptors, const Map& map, int max_candidates) const {
  BowVector bow;
  vocabulary_->Transform(descriptors, &bow);
  QueryFilter filter;
  filter.only_maps = {map.id()};
  // ORB-SLAM's relocalization grouping: no minimum score, keep groups within 75 % of the best.
  CandidateOptions options;
  options.max_results = max_candidates;
  const auto covisibility = [&map](KeyframeId id, int n) {
    const auto kf = map.keyframe(id);
    return kf ? kf->BestCovisible(n) : std::vector<KeyframeId>{};
  };
  std::vector<std::shared_ptr<KeyFrame>> out;
  for (const PlaceCandidate& c : database_.DetectCandidates(bow, filter, options, covisibility)) {
    if (auto kf = map.keyframe(c.best.keyframe); kf && !kf->bad()) out.push_back(std::move(kf));
  }
  return out;
}

}  // namespace ccm
