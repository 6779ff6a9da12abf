// Common interface for anything that delivers monocular frames in time order:
// dataset readers (EuRoC, TUM, KITTI), the scene simulator rendering in process,
// and live cameras. The VO front end and tools consume frames only through it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "slam_core/feature/frame.h"
#include "slam_core/geometry/camera.h"

namespace ccm {

/// Pull-style frame source. Not thread-safe: one consumer thread owns it.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Next frame, or std::nullopt at the end of the sequence. Errors (unreadable image)
  /// are reported through error() after returning nullopt.
  virtual std::optional<Frame> Next() = 0;
  /// Calibration of the camera that produced the frames.
  virtual const CameraIntrinsics& intrinsics() const = 0;
  /// Total number of frames if known, otherwise -1 (live camera).
  virtual int64_t size() const = 0;
  /// Empty if the source ended normally; otherwise a human-readable reason.
  virtual const std::string& error() const = 0;
};

}  // namespace ccm
