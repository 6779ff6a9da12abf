#include "slam_core/matching/window_matcher.h"

#include "slam_core/matching/match_internal.h"

namespace ccm {

std::string WindowMatchOptions::Validate() const {
  if (!(window_px > 0.f)) return "window_px must be > 0";
  if (max_distance < 0 || max_distance > 256) return "max_distance must be in [0, 256]";
  if (!(ratio > 0.0)) return "ratio must be > 0";
  if (max_level < 0) return "max_level must be >= 0";
  return rotation.Validate();
}

std::vector<Eigen::Vector2f> InitialSearchCentres(const FrameFeatures& features1) {
  std::vector<Eigen::Vector2f> centres;
  centres.reserve(features1.size());
  for (const Keypoint& kp : features1.keypoints) centres.emplace_back(kp.u, kp.v);
  return centres;
}

std::vector<FeatureMatch> MatchInWindow(const FrameFeatures& features1,
                                        const FrameFeatures& features2, const KeypointGrid& grid2,
                                        const WindowMatchOptions& options,
                                        std::vector<Eigen::Vector2f>* search_centres) {
  if (search_centres->size() != features1.size() || grid2.size() != features2.size()) return {};
  std::vector<internal::BestTwo> best(features1.size());
  std::vector<int> nearby;
  for (size_t i = 0; i < features1.size(); ++i) {
    if (features1.keypoints[i].level > options.max_level) continue;
    const Eigen::Vector2f& c = (*search_centres)[i];
    grid2.FeaturesInArea(c.x(), c.y(), options.window_px, 0, options.max_level, &nearby);
    for (int j : nearby) {
      best[i].Add(j, HammingDistance(features1.descriptors[i], features2.descriptors[j]));
    }
  }
  std::vector<FeatureMatch> matches =
      internal::ResolveOneToOne(best, features2.size(), [&](int, const internal::BestTwo& b) {
        return b.best <= options.max_distance && b.PassesRatio(options.ratio);
      });
  if (options.check_rotation) {
    FilterByRotation(features1.keypoints, features2.keypoints, options.rotation, &matches);
  }
  for (const FeatureMatch& m : matches) {
    const Keypoint& kp2 = features2.keypoints[m.index2];
    (*search_centres)[m.index1] = Eigen::Vector2f(kp2.u, kp2.v);
  }
  return matches;
}

}  // namespace ccm
