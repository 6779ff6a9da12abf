// A contiguous slice of another FrameSource: frames first..last (0-based, inclusive) of the
// sequence. Lets one recorded flight stand for several agents (KITTI frames 0-99 and 60-159
// as two cars on the same road) without copying the dataset. Frames keep their stamps and
// ground truth, so they stay comparable with the full sequence's ground truth.
//
//   auto range = ParseFrameRange("60-159", &status);
//   auto source = LimitFrames(OpenDataset(dir, DatasetFormat::kAuto, &status), *range, &status);
//
// Not thread-safe (one consumer, like every FrameSource).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "slam_core/io/frame_source.h"
#include "slam_core/io/io_status.h"

namespace ccm {

struct FrameRange {
  int64_t first = 0;  ///< index of the first frame delivered
  int64_t last = -1;  ///< index of the last frame delivered (inclusive); -1: to the end

  /// Frames of a sequence of `total` frames (-1: unknown) that fall in the range; -1 if unknown.
  int64_t CountIn(int64_t total) const;
};

/// "FIRST-LAST" (e.g. "60-159") or "FIRST-" (to the end); nullopt with a message otherwise.
std::optional<FrameRange> ParseFrameRange(const std::string& text, IoStatus* status);

class FrameRangeSource : public FrameSource {
 public:
  FrameRangeSource(std::unique_ptr<FrameSource> inner, FrameRange range);

  std::optional<Frame> Next() override;
  const CameraIntrinsics& intrinsics() const override { return inner_->intrinsics(); }
  int64_t size() const override { return range_.CountIn(inner_->size()); }
  const std::string& error() const override { return error_.empty() ? inner_->error() : error_; }

 private:
  std::unique_ptr<FrameSource> inner_;
  FrameRange range_;
  int64_t next_index_ = 0;  ///< index in the inner sequence of the frame Next() reads
  std::string error_;
};

/// Wraps `inner` in a FrameRangeSource. Fails (nullptr and a message) when `inner` is null
/// or the range starts beyond a sequence of known length, so a typo in a range is reported
/// before a replay starts rather than as an agent with no frames.
std::unique_ptr<FrameSource> LimitFrames(std::unique_ptr<FrameSource> inner, FrameRange range, IoStatus* status);

}  // namespace ccm
