#include "slam_core/matching/epipolar_matcher.h"

#include <algorithm>
#include <cmath>

#include "slam_core/matching/match_internal.h"

namespace ccm {
namespace {

/// Unit normal (in camera 2) of the plane through both centres and ray 1; zero if undefined.
Eigen::Vector3d PlaneNormal(const Eigen::Vector3d& bearing1, const Eigen::Vector3d& baseline_dir,
                            const Eigen::Matrix3d& r21) {
  const Eigen::Vector3d n = baseline_dir.cross(r21 * bearing1);
  const double len = n.norm();
  return len > 1e-12 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

bool Skipped(const std::vector<bool>* skip, size_t k) {
  return skip != nullptr && k < skip->size() && (*skip)[k];
}

/// Per keypoint of view 2: sine of the allowed angular band (from its level's pixel sigma),
/// or a negative value when it cannot be matched (skipped, or too close to the epipole).
std::vector<double> BandSines(const EpipolarView& view2, const Eigen::Vector3d& baseline_dir,
                              const ScalePyramid& pyramid, const EpipolarMatchOptions& options) {
  const int top = static_cast<int>(pyramid.scale.size()) - 1;
  std::vector<double> band_sin(view2.features.size(), -1.0);
  for (size_t j = 0; j < band_sin.size(); ++j) {
    if (Skipped(view2.skip, j)) continue;
    const int level = std::clamp(view2.features.keypoints[j].level, 0, top);
    const double px_to_rad = pyramid.scale[level] * options.rad_per_px;
    // Both directions along the baseline carry no parallax.
    const double epipole_rad = std::min(options.min_epipole_distance_px * px_to_rad, M_PI / 2);
    if (std::fabs(baseline_dir.dot(view2.bearings[j])) > std::cos(epipole_rad)) continue;
    band_sin[j] = std::sin(std::min(std::sqrt(options.chi2_threshold) * px_to_rad, M_PI / 2));
  }
  return band_sin;
}

}  // namespace

std::string EpipolarMatchOptions::Validate() const {
  if (max_distance < 0 || max_distance > 256) return "max_distance must be in [0, 256]";
  if (!(ratio > 0.0)) return "ratio must be > 0";
  if (!(rad_per_px > 0.0)) return "rad_per_px must be > 0 (e.g. 1 / fx)";
  if (!(chi2_threshold > 0.0)) return "chi2_threshold must be > 0";
  if (!(min_epipole_distance_px >= 0.0)) return "min_epipole_distance_px must be >= 0";
  return rotation.Validate();
}

double EpipolarAngle(const Eigen::Vector3d& bearing1, const Eigen::Vector3d& bearing2,
                     const SE3& cam2_from_cam1) {
  const Eigen::Vector3d& t = cam2_from_cam1.translation();
  if (t.norm() < 1e-12) return 0.0;
  const Eigen::Vector3d n = PlaneNormal(bearing1, t.normalized(), cam2_from_cam1.rotation_matrix());
  return std::asin(std::min(1.0, std::fabs(n.dot(bearing2.normalized()))));
}

std::vector<FeatureMatch> MatchEpipolar(const EpipolarView& view1, const EpipolarView& view2,
                                        const SE3& cam2_from_cam1, const ScalePyramid& pyramid,
                                        const EpipolarMatchOptions& options,
                                        const MatchGroups* groups) {
  const size_t n1 = view1.features.size(), n2 = view2.features.size();
  const Eigen::Vector3d& t = cam2_from_cam1.translation();
  if (view1.bearings.size() != n1 || view2.bearings.size() != n2 || pyramid.scale.empty() ||
      !(options.rad_per_px > 0.0) || t.norm() < 1e-12) {
    return {};
  }
  const Eigen::Vector3d baseline_dir = t.normalized();  // camera 1's centre seen from camera 2
  const Eigen::Matrix3d r21 = cam2_from_cam1.rotation_matrix();
  const std::vector<double> band_sin = BandSines(view2, baseline_dir, pyramid, options);
  std::vector<Eigen::Vector3d> normal1(n1, Eigen::Vector3d::Zero());
  for (size_t i = 0; i < n1; ++i) {
    if (!Skipped(view1.skip, i)) normal1[i] = PlaneNormal(view1.bearings[i], baseline_dir, r21);
  }
  // The ratio test runs among the epipolar-consistent candidates only: elsewhere in the image a
  // similar-looking corner is no ambiguity.
  std::vector<internal::BestTwo> best(n1);
  internal::ForEachPair(n1, n2, groups, [&](int i, int j) {
    if (band_sin[j] < 0.0 || normal1[i].isZero()) return;
    if (std::fabs(normal1[i].dot(view2.bearings[j])) > band_sin[j]) return;
    best[i].Add(j, HammingDistance(view1.features.descriptors[i], view2.features.descriptors[j]));
  });
  std::vector<FeatureMatch> matches =
      internal::ResolveOneToOne(best, n2, [&](int, const internal::BestTwo& b) {
        return b.best <= options.max_distance && b.PassesRatio(options.ratio);
      });
  if (options.check_rotation) {
    FilterByRotation(view1.features.keypoints, view2.features.keypoints, options.rotation,
                     &matches);
  }
  return matches;
}

}  // namespace ccm
