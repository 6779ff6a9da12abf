#include "slam_core/matching/epipolar_matcher.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

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

// All pairs without groups: a new keyframe is matched against ~10-20 neighbours, about 10^6
// pairs each of which a few percent lie in the band, and visiting every pair was 7-18 % of an
// agent's CPU (docs/deployment.md "Footprint by thread"). A float pass over view 2 in
// structure-of-arrays form, which the compiler vectorizes, keeps a superset of the band (its
// margin is far above float rounding on unit vectors); `visit` then applies the exact double
// test to those pairs in the same order, so the matches are exactly those of visiting every
// pair. Only the keypoints that can match enter the pass (in a tracked keyframe a third to a
// half already hold a map point), and a block's hits are taken from a bit mask, not by
// visiting its 16 lanes again. (Sorting view 2 by its angle around the baseline and visiting
// only the window a plane reaches was slower: under forward motion most keypoints sit near
// the epipole, where the window is wide.)
template <typename Visit>
void ScanAllPairs(const std::vector<Eigen::Vector3d>& normal1, const EpipolarView& view2,
                  const std::vector<double>& band_sin, Visit&& visit) {
  constexpr float kMargin = 1e-4f;
  constexpr size_t kBlock = 16;  // a block without a hit (most of them) costs a few vector ops
  std::vector<int> index2;  // the candidates of view 2, in increasing order
  index2.reserve(band_sin.size());
  for (size_t j = 0; j < band_sin.size(); ++j) {
    if (band_sin[j] >= 0.0) index2.push_back(static_cast<int>(j));
  }
  const size_t n2 = index2.size(), padded = (n2 + kBlock - 1) / kBlock * kBlock;
  // Padding: band -1 is never reached (|dot| - band >= 1).
  std::vector<float> x(padded, 0.0f), y(padded, 0.0f), z(padded, 0.0f), band(padded, -1.0f);
  for (size_t c = 0; c < n2; ++c) {
    const Eigen::Vector3d& b = view2.bearings[index2[c]];
    x[c] = static_cast<float>(b.x());
    y[c] = static_cast<float>(b.y());
    z[c] = static_cast<float>(b.z());
    band[c] = static_cast<float>(band_sin[index2[c]]) + kMargin;
  }
  float d[kBlock];
  for (size_t i = 0; i < normal1.size(); ++i) {
    if (normal1[i].isZero()) continue;
    const float nx = static_cast<float>(normal1[i].x()), ny = static_cast<float>(normal1[i].y()),
                nz = static_cast<float>(normal1[i].z());
    for (size_t c0 = 0; c0 < padded; c0 += kBlock) {
      int hit = 0;
      for (size_t k = 0; k < kBlock; ++k) {
        d[k] = std::fabs(nx * x[c0 + k] + ny * y[c0 + k] + nz * z[c0 + k]) - band[c0 + k];
        hit |= d[k] <= 0.0f;
      }
      if (hit == 0) continue;
      std::uint32_t mask = 0;  // branch-free: a block's few hits are scattered
      for (size_t k = 0; k < kBlock; ++k) mask |= static_cast<std::uint32_t>(d[k] <= 0.0f) << k;
      while (mask != 0) {
        visit(static_cast<int>(i), index2[c0 + __builtin_ctz(mask)]);
        mask &= mask - 1;
      }
    }
  }
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
  const auto visit = [&](int i, int j) {
    if (band_sin[j] < 0.0 || normal1[i].isZero()) return;
    if (std::fabs(normal1[i].dot(view2.bearings[j])) > band_sin[j]) return;
    best[i].Add(j, HammingDistance(view1.features.descriptors[i], view2.features.descriptors[j]));
  };
  if (groups != nullptr) {
    internal::ForEachPair(n1, n2, groups, visit);
  } else {
    ScanAllPairs(normal1, view2, band_sin, visit);
  }
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
