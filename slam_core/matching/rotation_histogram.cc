#include "slam_core/matching/rotation_histogram.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace ccm {

std::string RotationCheckOptions::Validate() const {
  if (num_bins < 1 || num_bins > 360) return "num_bins must be in [1, 360]";
  if (keep_bins < 1 || keep_bins > num_bins) return "keep_bins must be in [1, num_bins]";
  if (!(min_bin_ratio >= 0.0 && min_bin_ratio <= 1.0)) return "min_bin_ratio must be in [0, 1]";
  return "";
}

std::vector<bool> RotationConsistentMask(const std::vector<float>& angle_change_deg,
                                         const RotationCheckOptions& options) {
  const int n = std::max(options.num_bins, 1);
  std::vector<int> bin_of(angle_change_deg.size());
  std::vector<int> count(n, 0);
  for (size_t k = 0; k < angle_change_deg.size(); ++k) {
    double a = std::fmod(static_cast<double>(angle_change_deg[k]), 360.0);
    if (a < 0) a += 360.0;
    const int bin = std::min(n - 1, static_cast<int>(a * n / 360.0));
    bin_of[k] = bin;
    ++count[bin];
  }
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return count[a] > count[b]; });
  std::vector<bool> keep_bin(n, false);
  const int largest = count[order[0]];
  for (int r = 0; r < std::min(options.keep_bins, n); ++r) {
    const int c = count[order[r]];
    if (c == 0 || (r > 0 && c < options.min_bin_ratio * largest)) break;
    keep_bin[order[r]] = true;
  }
  std::vector<bool> keep(angle_change_deg.size());
  for (size_t k = 0; k < keep.size(); ++k) keep[k] = keep_bin[bin_of[k]];
  return keep;
}

void FilterByRotation(const std::vector<Keypoint>& keypoints1,
                      const std::vector<Keypoint>& keypoints2, const RotationCheckOptions& options,
                      std::vector<FeatureMatch>* matches) {
  std::vector<float> change;
  change.reserve(matches->size());
  for (const FeatureMatch& m : *matches) {
    change.push_back(keypoints2[m.index2].angle_deg - keypoints1[m.index1].angle_deg);
  }
  FilterByAngleChange(change, options, matches);
}

void FilterByAngleChange(const std::vector<float>& angle_change_deg,
                         const RotationCheckOptions& options, std::vector<FeatureMatch>* matches) {
  if (angle_change_deg.size() != matches->size()) return;
  const std::vector<bool> keep = RotationConsistentMask(angle_change_deg, options);
  size_t out = 0;
  for (size_t k = 0; k < matches->size(); ++k) {
    if (keep[k]) (*matches)[out++] = (*matches)[k];
  }
  matches->resize(out);
}

}  // namespace ccm
