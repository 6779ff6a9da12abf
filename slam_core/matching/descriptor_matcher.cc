#include "slam_core/matching/descriptor_matcher.h"

#include <algorithm>

#include "slam_core/matching/match_internal.h"

namespace ccm {

std::string DescriptorMatchOptions::Validate() const {
  if (max_distance < 0 || max_distance > 256) return "max_distance must be in [0, 256]";
  if (!(ratio > 0.0)) return "ratio must be > 0";
  return rotation.Validate();
}

std::vector<FeatureMatch> MatchDescriptors(const std::vector<OrbDescriptor>& descriptors1,
                                           const std::vector<OrbDescriptor>& descriptors2,
                                           const DescriptorMatchOptions& options,
                                           const MatchGroups* groups) {
  const size_t n1 = descriptors1.size(), n2 = descriptors2.size();
  std::vector<internal::BestTwo> best12(n1), best21(options.mutual ? n2 : 0);
  internal::ForEachPair(n1, n2, groups, [&](int i, int j) {
    const int d = HammingDistance(descriptors1[i], descriptors2[j]);
    best12[i].Add(j, d);
    if (options.mutual) best21[j].Add(i, d);
  });
  return internal::ResolveOneToOne(best12, n2, [&](int i, const internal::BestTwo& b) {
    return b.best <= options.max_distance && b.PassesRatio(options.ratio) &&
           (!options.mutual || best21[b.index].index == i);
  });
}

std::vector<FeatureMatch> MatchFeatures(const FrameFeatures& features1,
                                        const FrameFeatures& features2,
                                        const DescriptorMatchOptions& options,
                                        const MatchGroups* groups) {
  std::vector<FeatureMatch> matches =
      MatchDescriptors(features1.descriptors, features2.descriptors, options, groups);
  if (options.check_rotation) {
    FilterByRotation(features1.keypoints, features2.keypoints, options.rotation, &matches);
  }
  return matches;
}

}  // namespace ccm
