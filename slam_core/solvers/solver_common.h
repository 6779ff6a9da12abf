// Shared vocabulary of the geometric solvers: RANSAC options, failure status and the
// pixel <-> angle conversion. Solvers work on unit bearing vectors so that any
// ccm::CameraModel can feed them (callers Unproject keypoints); thresholds are given in
// pixels together with the caller's focal length and converted to angles here.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

namespace ccm::solvers {

enum class SolverStatus {
  kOk = 0,
  kInvalidInput,       // options fail Validate() or input sizes differ
  kTooFewPoints,       // fewer correspondences than the minimal sample
  kRansacFailed,       // no hypothesis could be computed
  kTooFewInliers,      // best hypothesis below min_inliers
  kDegenerate,         // data cannot determine the model (e.g. collinear points)
  kLowParallax,        // two-view initialization: baseline too small
  kAmbiguous,          // two-view initialization: no clear winner among motions
};

const char* SolverStatusName(SolverStatus status);

/// Options of one RANSAC run. Every solver embeds one of these in its own Options.
struct RansacOptions {
  /// Inlier threshold in pixels at the focal length below (per image/residual).
  double threshold_px = 2.0;
  /// Focal length in pixels used to turn threshold_px into an angle. Must be set by the
  /// caller (e.g. camera fx); 0 fails Validate() on purpose.
  double focal_px = 0.0;
  /// Hard cap on hypotheses; the adaptive count from `confidence` usually stops earlier.
  int max_iterations = 1000;
  /// Probability that at least one all-inlier sample was drawn, in (0, 1).
  double confidence = 0.999;
  /// Seed of the sample generator: equal inputs and seed give equal results.
  std::uint64_t seed = 42;

  /// Empty if usable, otherwise what is wrong.
  std::string Validate() const;
  /// threshold_px as an angle in radians.
  double ThresholdAngleRad() const { return std::atan2(threshold_px, focal_px); }
};

/// Converts an angular error to the pixel error it causes at focal length focal_px.
inline double AngleToPixels(double angle_rad, double focal_px) { return angle_rad * focal_px; }

}  // namespace ccm::solvers
