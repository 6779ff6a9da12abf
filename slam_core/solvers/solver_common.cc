#include "slam_core/solvers/solver_common.h"

namespace ccm::solvers {

const char* SolverStatusName(SolverStatus status) {
  switch (status) {
    case SolverStatus::kOk: return "ok";
    case SolverStatus::kInvalidInput: return "invalid input";
    case SolverStatus::kTooFewPoints: return "too few points";
    case SolverStatus::kRansacFailed: return "ransac failed";
    case SolverStatus::kTooFewInliers: return "too few inliers";
    case SolverStatus::kDegenerate: return "degenerate";
    case SolverStatus::kLowParallax: return "low parallax";
    case SolverStatus::kAmbiguous: return "ambiguous";
  }
  return "unknown";
}

std::string RansacOptions::Validate() const {
  if (!(threshold_px > 0.0)) return "ransac.threshold_px must be > 0";
  if (!(focal_px > 0.0)) return "ransac.focal_px must be > 0 (set it to the camera focal length)";
  if (max_iterations < 1) return "ransac.max_iterations must be >= 1";
  if (!(confidence > 0.0 && confidence < 1.0)) return "ransac.confidence must be in (0, 1)";
  return "";
}

}  // namespace ccm::solvers
