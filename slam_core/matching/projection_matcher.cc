#include "slam_core/matching/projection_matcher.h"

#include <algorithm>

#include "slam_core/matching/match_internal.h"

namespace ccm {

std::string ProjectionMatchOptions::Validate() const {
  if (!(radius_px > 0.0)) return "radius_px must be > 0";
  if (max_distance < 0 || max_distance > 256) return "max_distance must be in [0, 256]";
  if (!(ratio > 0.0)) return "ratio must be > 0";
  if (levels_below < 0 || levels_above < 0) return "levels_below/above must be >= 0";
  return rotation.Validate();
}

std::vector<FeatureMatch> MatchByProjection(const std::vector<ProjectionCandidate>& candidates,
                                            const FrameFeatures& features, const KeypointGrid& grid,
                                            const ScalePyramid& pyramid,
                                            const ProjectionMatchOptions& options,
                                            const std::vector<bool>* keypoint_taken,
                                            const std::vector<float>* candidate_angles_deg) {
  const int num_levels = static_cast<int>(pyramid.scale.size());
  if (num_levels == 0 || grid.size() != features.size() ||
      (keypoint_taken && keypoint_taken->size() != features.size())) {
    return {};
  }
  std::vector<internal::BestTwo> best(candidates.size());
  std::vector<int> nearby;
  for (size_t c = 0; c < candidates.size(); ++c) {
    const ProjectionCandidate& cand = candidates[c];
    const int level = std::clamp(cand.level, 0, num_levels - 1);
    const float radius =
        static_cast<float>(options.radius_px * cand.radius_factor * pyramid.scale[level]);
    grid.FeaturesInArea(cand.u, cand.v, radius, std::max(0, level - options.levels_below),
                        level + options.levels_above, &nearby);
    for (int k : nearby) {
      if (keypoint_taken && (*keypoint_taken)[k]) continue;
      best[c].Add(k, HammingDistance(cand.descriptor, features.descriptors[k]),
                  features.keypoints[k].level);
    }
  }
  std::vector<FeatureMatch> matches =
      internal::ResolveOneToOne(best, features.size(), [&](int, const internal::BestTwo& b) {
        // Two similar keypoints on the same level make the association ambiguous; on
        // different levels they are usually the same corner detected twice.
        return b.best <= options.max_distance &&
               (b.best_level != b.second_level || b.PassesRatio(options.ratio));
      });
  if (options.check_rotation && candidate_angles_deg &&
      candidate_angles_deg->size() == candidates.size()) {
    std::vector<float> change;
    change.reserve(matches.size());
    for (const FeatureMatch& m : matches) {
      change.push_back(features.keypoints[m.index2].angle_deg - (*candidate_angles_deg)[m.index1]);
    }
    FilterByAngleChange(change, options.rotation, &matches);
  }
  return matches;
}

}  // namespace ccm
