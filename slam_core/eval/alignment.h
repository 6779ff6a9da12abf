// Least-squares alignment of estimated positions to ground-truth positions (Umeyama 1991),
// the same closed form evo uses for `-a` (SE(3)) and `-as` (Sim(3)). Monocular trajectories
// have arbitrary scale and need Sim(3); metric ones (stereo, VIO) are aligned in SE(3).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slam_core/geometry/sim3.h"

namespace ccm {

enum class AlignmentType { kNone, kSE3, kSim3 };

/// "none", "se3", "sim3"; nullopt otherwise.
std::optional<AlignmentType> ParseAlignmentType(const std::string& name);
const char* ToString(AlignmentType type);

/// gt_from_est = (s, R, t) minimising sum_i ||gt_i - (s R est_i + t)||^2, s = 1 unless
/// with_scale. Needs >= 3 points whose cross-covariance has rank >= 2 (not all on a line);
/// otherwise returns nullopt and says why in *error.
std::optional<Sim3> UmeyamaAlignment(const std::vector<Eigen::Vector3d>& est,
                                     const std::vector<Eigen::Vector3d>& gt, bool with_scale,
                                     std::string* error);

}  // namespace ccm
