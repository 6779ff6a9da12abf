// FrameSource over a list of image files with timestamps and optional ground truth. All
// dataset readers (EuRoC, TUM RGB-D, KITTI) parse their index files into this list at open
// time, so errors in index files surface before the first frame; images are decoded lazily
// (8-bit gray, colour converted) in Next(). Not thread-safe: one consumer owns it.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "slam_core/io/frame_source.h"
#include "slam_core/io/trajectory.h"

namespace ccm {

struct ImageEntry {
  int64_t stamp_ns = 0;
  std::string path;
  std::optional<SE3> world_from_cam_gt;
};

class ImageListSource : public FrameSource {
 public:
  ImageListSource(const CameraIntrinsics& intrinsics, std::vector<ImageEntry> entries);

  std::optional<Frame> Next() override;
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  int64_t size() const override { return static_cast<int64_t>(entries_.size()); }
  const std::string& error() const override { return error_; }

  /// The whole index (stamps, paths, ground truth) without decoding images.
  const std::vector<ImageEntry>& entries() const { return entries_; }
  /// Ground truth of the frames that have one, as a trajectory.
  Trajectory GroundTruth() const;
  /// Restarts at the first frame and clears the error.
  void Rewind();

 private:
  CameraIntrinsics intrinsics_;
  std::vector<ImageEntry> entries_;
  size_t next_ = 0;
  std::string error_;
};

/// Gives each entry the ground-truth pose with the nearest stamp if it is within max_dt_ns
/// (the others get none). Returns how many entries received a pose.
size_t AttachGroundTruth(const Trajectory& ground_truth, int64_t max_dt_ns,
                         std::vector<ImageEntry>* entries);

}  // namespace ccm
