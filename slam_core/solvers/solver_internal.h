// Helpers shared by the solver implementations (not part of the public API).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include <opengv/types.hpp>

namespace ccm::solvers::internal {

/// OpenGV seeds its problems from the clock or a fixed constant; re-seed from ours. Its
/// generator is a std::bind copy of rng_alg_, so it has to be rebuilt after seeding.
template <class Problem>
void SeedOpenGvProblem(Problem* problem, std::uint64_t seed) {
  problem->rng_alg_.seed(static_cast<std::uint32_t>(seed ^ (seed >> 32)));
  problem->rng_gen_ = std::make_shared<std::function<int()>>(
      std::bind(*problem->rng_dist_, problem->rng_alg_));
}

inline opengv::bearingVectors_t ToOpenGv(const std::vector<Eigen::Vector3d>& v) {
  return opengv::bearingVectors_t(v.begin(), v.end());
}

/// OpenGV's residual for one view: 1 - cos(angle); threshold for an angle.
inline double OneMinusCos(double angle_rad) { return 1.0 - std::cos(angle_rad); }

/// Number of RANSAC iterations needed to draw one all-inlier sample with probability
/// `confidence` when a fraction `inlier_ratio` of the data are inliers.
inline int AdaptiveIterations(double inlier_ratio, int sample_size, double confidence,
                              int max_iterations) {
  const double p_good = std::pow(std::clamp(inlier_ratio, 0.0, 1.0), sample_size);
  if (p_good <= 1e-12) return max_iterations;
  if (p_good >= 1.0 - 1e-12) return 1;
  const double k = std::log(1.0 - confidence) / std::log(1.0 - p_good);
  return static_cast<int>(std::min<double>(max_iterations, std::ceil(k)));
}

/// Draws `k` distinct indices in [0, n) (partial Fisher-Yates on a scratch vector).
inline void DrawSample(int n, int k, std::mt19937_64* rng, std::vector<int>* scratch,
                       std::vector<int>* sample) {
  if (static_cast<int>(scratch->size()) != n) {
    scratch->resize(n);
    for (int i = 0; i < n; ++i) (*scratch)[i] = i;
  }
  sample->resize(k);
  for (int i = 0; i < k; ++i) {
    std::uniform_int_distribution<int> pick(i, n - 1);
    std::swap((*scratch)[i], (*scratch)[pick(*rng)]);
    (*sample)[i] = (*scratch)[i];
  }
}

inline int CountTrue(const std::vector<bool>& mask) {
  return static_cast<int>(std::count(mask.begin(), mask.end(), true));
}

/// Angle between two (not necessarily unit) vectors, robust for small angles.
/// Indices i with mask[i] set (RANSAC inlier mask -> index list for a refit).
inline std::vector<int> MaskToIndices(const std::vector<bool>& mask) {
  std::vector<int> idx;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (mask[i]) idx.push_back(static_cast<int>(i));
  }
  return idx;
}

inline double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

}  // namespace ccm::solvers::internal
