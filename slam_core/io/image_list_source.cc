#include "slam_core/io/image_list_source.h"

#include <algorithm>
#include <cstdlib>
#include <numeric>

#include <opencv2/imgcodecs.hpp>

namespace ccm {

ImageListSource::ImageListSource(const CameraIntrinsics& intrinsics, std::vector<ImageEntry> entries)
    : intrinsics_(intrinsics), entries_(std::move(entries)) {}

std::optional<Frame> ImageListSource::Next() {
  if (next_ >= entries_.size() || !error_.empty()) return std::nullopt;
  const ImageEntry& entry = entries_[next_];
  Frame frame;
  frame.stamp_ns = entry.stamp_ns;
  frame.world_from_cam_gt = entry.world_from_cam_gt;
  frame.source_name = entry.path;
  frame.image = cv::imread(entry.path, cv::IMREAD_GRAYSCALE);
  if (frame.image.empty()) {
    error_ = "cannot read image " + entry.path;
    return std::nullopt;
  }
  if (frame.image.cols != intrinsics_.width_px || frame.image.rows != intrinsics_.height_px) {
    error_ = "image " + entry.path + " is " + std::to_string(frame.image.cols) + "x" +
             std::to_string(frame.image.rows) + " but the calibration says " +
             std::to_string(intrinsics_.width_px) + "x" + std::to_string(intrinsics_.height_px);
    return std::nullopt;
  }
  ++next_;
  return frame;
}

Trajectory ImageListSource::GroundTruth() const {
  Trajectory gt;
  for (const ImageEntry& e : entries_) {
    if (e.world_from_cam_gt) gt.push_back(StampedPose{e.stamp_ns, *e.world_from_cam_gt});
  }
  return gt;
}

void ImageListSource::Rewind() {
  next_ = 0;
  error_.clear();
}

size_t AttachGroundTruth(const Trajectory& ground_truth, int64_t max_dt_ns,
                         std::vector<ImageEntry>* entries) {
  // Sorted view of the ground truth so each lookup is a binary search.
  std::vector<size_t> order(ground_truth.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return ground_truth[a].stamp_ns < ground_truth[b].stamp_ns;
  });
  size_t attached = 0;
  for (ImageEntry& entry : *entries) {
    entry.world_from_cam_gt.reset();
    auto it = std::lower_bound(order.begin(), order.end(), entry.stamp_ns,
                               [&](size_t i, int64_t s) { return ground_truth[i].stamp_ns < s; });
    int64_t best_dt = -1;
    size_t best = 0;
    for (auto c : {it, it == order.begin() ? it : it - 1}) {
      if (c == order.end()) continue;
      const int64_t dt = std::llabs(ground_truth[*c].stamp_ns - entry.stamp_ns);
      if (best_dt < 0 || dt < best_dt) best_dt = dt, best = *c;
    }
    if (best_dt >= 0 && best_dt <= max_dt_ns) {
      entry.world_from_cam_gt = ground_truth[best].world_from_cam;
      ++attached;
    }
  }
  return attached;
}

}  // namespace ccm
