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
  /// A live camera: it does not wait for the reader, so frames are neither paced by their
  /// stamps nor held back while local mapping catches up (a late frame is skipped instead).
  virtual bool live() const { return false; }
  /// Frames a live source skipped because the reader was behind (0 for recorded input).
  virtual int64_t frames_skipped() const { return 0; }
};

}  // namespace ccm
