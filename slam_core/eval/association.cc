#include "slam_core/eval/association.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>

namespace ccm {

bool AssociationOptions::Validate(std::string* error) const {
  if (!(max_dt_s >= 0.0) || !std::isfinite(max_dt_s)) {
    *error = "association max_dt_s must be >= 0";
    return false;
  }
  if (!std::isfinite(est_offset_s)) {
    *error = "association est_offset_s must be finite";
    return false;
  }
  return true;
}

std::vector<AssociatedPair> AssociateByStamp(const Trajectory& gt, const Trajectory& est,
                                             const AssociationOptions& options) {
  const int64_t offset_ns = static_cast<int64_t>(std::llround(options.est_offset_s * 1e9));
  const int64_t max_dt_ns = static_cast<int64_t>(std::llround(options.max_dt_s * 1e9));
  // evo iterates over the shorter trajectory (the ground truth on ties goes second).
  const bool est_shorter = est.size() <= gt.size();
  const Trajectory& shorter = est_shorter ? est : gt;
  const Trajectory& longer = est_shorter ? gt : est;
  const int64_t shorter_offset = est_shorter ? offset_ns : 0;
  const int64_t longer_offset = est_shorter ? 0 : offset_ns;

  std::vector<size_t> order(longer.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return longer[a].stamp_ns < longer[b].stamp_ns;
  });
  std::vector<AssociatedPair> pairs;
  for (size_t i = 0; i < shorter.size(); ++i) {
    const int64_t stamp = shorter[i].stamp_ns + shorter_offset - longer_offset;
    auto it = std::lower_bound(order.begin(), order.end(), stamp,
                               [&](size_t k, int64_t s) { return longer[k].stamp_ns < s; });
    // Nearest of the two neighbours; on a tie the earlier one (numpy argmin order).
    size_t best = order.size();
    int64_t best_dt = 0;
    if (it != order.begin()) {
      best = *(it - 1);
      best_dt = std::llabs(longer[best].stamp_ns - stamp);
    }
    if (it != order.end()) {
      const int64_t dt = std::llabs(longer[*it].stamp_ns - stamp);
      if (best == order.size() || dt < best_dt) best = *it, best_dt = dt;
    }
    if (best == order.size() || best_dt > max_dt_ns) continue;
    pairs.push_back(est_shorter ? AssociatedPair{best, i} : AssociatedPair{i, best});
  }
  return pairs;
}

}  // namespace ccm
