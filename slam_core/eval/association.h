// Timestamp association of a ground-truth and an estimated trajectory, as evo does
// (evo.core.sync.associate_trajectories): every pose of the SHORTER trajectory is paired with
// the nearest-in-time pose of the longer one if |dt| <= max_dt_s. Pairs come in the order of
// the shorter trajectory.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "slam_core/io/trajectory.h"

namespace ccm {

struct AssociationOptions {
  double max_dt_s = 0.01;     ///< [s] tolerance, evo's --t_max_diff (default 0.01 s)
  double est_offset_s = 0.0;  ///< [s] added to the estimate's stamps, evo's --t_offset
  bool Validate(std::string* error) const;
};

struct AssociatedPair {
  size_t gt_index = 0;
  size_t est_index = 0;
};

std::vector<AssociatedPair> AssociateByStamp(const Trajectory& gt, const Trajectory& est,
                                             const AssociationOptions& options);

}  // namespace ccm
