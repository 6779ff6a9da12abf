#include "slam_core/eval/metrics.h"

#include <algorithm>
#include <cmath>

namespace ccm {

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<size_t>(q * (values.size() - 1) + 0.5))];
}

double PathLengthM(const std::vector<SE3>& poses) {
  double length = 0.0;
  for (size_t i = 1; i < poses.size(); ++i) length += (poses[i].translation() - poses[i - 1].translation()).norm();
  return length;
}

ErrorStats ComputeStats(const std::vector<double>& values) {
  ErrorStats s;
  s.count = values.size();
  if (values.empty()) return s;
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  double sum = 0.0;
  for (double v : sorted) {
    sum += v;
    s.sse += v * v;
  }
  const double n = static_cast<double>(s.count);
  s.mean = sum / n;
  s.rmse = std::sqrt(s.sse / n);
  double var = 0.0;
  for (double v : sorted) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / n);
  s.min = sorted.front();
  s.max = sorted.back();
  const size_t mid = s.count / 2;
  s.median = s.count % 2 == 1 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  return s;
}

std::vector<double> AbsoluteTranslationErrors(const std::vector<SE3>& gt,
                                              const std::vector<SE3>& est) {
  std::vector<double> errors(std::min(gt.size(), est.size()));
  for (size_t i = 0; i < errors.size(); ++i) {
    errors[i] = (est[i].translation() - gt[i].translation()).norm();
  }
  return errors;
}

double RotationAngleDeg(const Eigen::Quaterniond& q) {
  // atan2 form is accurate near 0 and 180 degrees, unlike acos((trace - 1) / 2).
  const double angle_rad = 2.0 * std::atan2(q.vec().norm(), std::fabs(q.w()));
  return angle_rad * 180.0 / M_PI;
}

bool RpeOptions::Validate(std::string* error) const {
  if (unit == RpeDeltaUnit::kFrames && !(delta >= 1.0 && delta == std::floor(delta))) {
    *error = "RPE delta in frames must be an integer >= 1";
    return false;
  }
  if (unit == RpeDeltaUnit::kMeters && !(delta > 0.0 && std::isfinite(delta))) {
    *error = "RPE delta in metres must be > 0";
    return false;
  }
  return true;
}

namespace {

std::vector<std::pair<size_t, size_t>> PairsByPath(const std::vector<SE3>& gt, double delta_m,
                                                   bool all_pairs) {
  std::vector<std::pair<size_t, size_t>> pairs;
  if (gt.empty()) return pairs;
  if (all_pairs) {
    // From every i, the j > i whose travelled distance is closest to delta, kept if within
    // 10% of delta (evo's default rel_delta_tol = 0.1).
    std::vector<double> dist(gt.size(), 0.0);
    for (size_t i = 1; i < gt.size(); ++i) {
      dist[i] = dist[i - 1] + (gt[i].translation() - gt[i - 1].translation()).norm();
    }
    for (size_t i = 0; i + 1 < gt.size(); ++i) {
      auto it = std::lower_bound(dist.begin() + i + 1, dist.end(), dist[i] + delta_m);
      size_t best = it == dist.end() ? gt.size() - 1 : static_cast<size_t>(it - dist.begin());
      if (best > i + 1 && std::fabs(dist[best - 1] - dist[i] - delta_m) <
                              std::fabs(dist[best] - dist[i] - delta_m)) {
        --best;
      }
      if (std::fabs(dist[best] - dist[i] - delta_m) <= 0.1 * delta_m) pairs.emplace_back(i, best);
    }
    return pairs;
  }
  std::vector<size_t> ids;
  double path = 0.0;
  for (size_t i = 0; i < gt.size(); ++i) {
    if (i > 0) path += (gt[i].translation() - gt[i - 1].translation()).norm();
    if (path >= delta_m) {
      ids.push_back(i);
      path = 0.0;
    }
  }
  for (size_t k = 0; k + 1 < ids.size(); ++k) pairs.emplace_back(ids[k], ids[k + 1]);
  return pairs;
}

}  // namespace

std::vector<std::pair<size_t, size_t>> RpePairs(const std::vector<SE3>& gt, const RpeOptions& options) {
  if (options.unit == RpeDeltaUnit::kMeters) return PairsByPath(gt, options.delta, options.all_pairs);
  const size_t delta = static_cast<size_t>(options.delta);
  std::vector<std::pair<size_t, size_t>> pairs;
  const size_t step = options.all_pairs ? 1 : delta;
  for (size_t i = 0; i + delta < gt.size(); i += step) pairs.emplace_back(i, i + delta);
  return pairs;
}

RpeResult ComputeRpe(const std::vector<SE3>& gt, const std::vector<SE3>& est,
                     const RpeOptions& options) {
  RpeResult result;
  if (gt.size() != est.size()) return result;
  result.pairs = RpePairs(gt, options);
  for (const auto& [i, j] : result.pairs) {
    const SE3 gt_rel = gt[i].inverse() * gt[j];
    const SE3 est_rel = est[i].inverse() * est[j];
    const SE3 error = gt_rel.inverse() * est_rel;
    result.translation_errors_m.push_back(error.translation().norm());
    result.rotation_errors_deg.push_back(RotationAngleDeg(error.rotation()));
  }
  result.translation_m = ComputeStats(result.translation_errors_m);
  result.rotation_deg = ComputeStats(result.rotation_errors_deg);
  return result;
}

namespace {

// RMS distance of positions[first..last] to their centroid.
double Spread(const std::vector<SE3>& poses, size_t first, size_t last) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t i = first; i <= last; ++i) mean += poses[i].translation();
  mean /= static_cast<double>(last - first + 1);
  double sum = 0.0;
  for (size_t i = first; i <= last; ++i) sum += (poses[i].translation() - mean).squaredNorm();
  return std::sqrt(sum / static_cast<double>(last - first + 1));
}

}  // namespace

ScaleDrift ComputeScaleDrift(const std::vector<SE3>& gt, const std::vector<SE3>& est, double window_m) {
  ScaleDrift result;
  const size_t n = std::min(gt.size(), est.size());
  if (n < 3 || !(window_m > 0.0)) return result;
  size_t first = 0;
  double path = 0.0;
  for (size_t i = 1; i < n; ++i) {
    path += (gt[i].translation() - gt[i - 1].translation()).norm();
    if (path < window_m) continue;
    const double est_spread = Spread(est, first, i);
    if (est_spread > 0.0) result.windows.push_back({first, i, path, Spread(gt, first, i) / est_spread});
    first = i;
    path = 0.0;
  }
  if (result.windows.empty()) return result;
  const auto [lo, hi] = std::minmax_element(result.windows.begin(), result.windows.end(),
                                            [](const ScaleWindow& a, const ScaleWindow& b) { return a.scale < b.scale; });
  result.min_scale = lo->scale;
  result.max_scale = hi->scale;
  if (result.windows.size() >= 2) result.max_over_min = hi->scale / lo->scale;
  return result;
}

}  // namespace ccm
