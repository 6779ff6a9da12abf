#include "slam_core/io/frame_range_source.h"

#include <algorithm>
#include <cctype>

namespace ccm {
namespace {

// A non-negative decimal integer filling all of `s`; nullopt otherwise (no sign, no spaces).
std::optional<int64_t> ParseIndex(const std::string& s) {
  if (s.empty() || s.size() > 12) return std::nullopt;
  int64_t v = 0;
  for (const char c : s) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return std::nullopt;
    v = 10 * v + (c - '0');
  }
  return v;
}

std::string RangeText(const FrameRange& r) {
  return std::to_string(r.first) + "-" + (r.last >= 0 ? std::to_string(r.last) : std::string());
}

}  // namespace

int64_t FrameRange::CountIn(int64_t total) const {
  if (total < 0) return last >= 0 ? last - first + 1 : -1;
  const int64_t end = last >= 0 ? std::min(last + 1, total) : total;
  return std::max<int64_t>(end - first, 0);
}

std::optional<FrameRange> ParseFrameRange(const std::string& text, IoStatus* status) {
  const size_t dash = text.find('-');
  const auto fail = [&] {
    *status = IoStatus::Error("frame range '" + text + "': expected FIRST-LAST (e.g. 60-159) or FIRST- (to the end)");
    return std::nullopt;
  };
  if (dash == std::string::npos) return fail();
  const auto first = ParseIndex(text.substr(0, dash));
  const std::string last_text = text.substr(dash + 1);
  const auto last = last_text.empty() ? std::optional<int64_t>(-1) : ParseIndex(last_text);
  if (!first || !last) return fail();
  if (*last >= 0 && *last < *first) {
    *status = IoStatus::Error("frame range '" + text + "': the last frame comes before the first");
    return std::nullopt;
  }
  *status = IoStatus::Ok();
  return FrameRange{*first, *last};
}

FrameRangeSource::FrameRangeSource(std::unique_ptr<FrameSource> inner, FrameRange range)
    : inner_(std::move(inner)), range_(range) {}

std::optional<Frame> FrameRangeSource::Next() {
  if (range_.last >= 0 && next_index_ > range_.last) return std::nullopt;
  // Frames before the range are read and dropped: FrameSource has no seek, and decoding a
  // few dozen images once is cheaper than a seek in every reader.
  while (next_index_ < range_.first) {
    if (!inner_->Next()) {
      if (inner_->error().empty()) {
        error_ = "frame range " + RangeText(range_) + " starts after the last frame (" + std::to_string(next_index_) +
                 " frames)";
      }
      return std::nullopt;
    }
    ++next_index_;
  }
  std::optional<Frame> frame = inner_->Next();
  if (frame) ++next_index_;
  return frame;
}

std::unique_ptr<FrameSource> LimitFrames(std::unique_ptr<FrameSource> inner, FrameRange range, IoStatus* status) {
  if (!inner) {
    if (status->ok()) *status = IoStatus::Error("no frame source to limit");
    return nullptr;
  }
  const int64_t total = inner->size();
  if (total >= 0 && (range.first >= total || range.last >= total)) {
    *status = IoStatus::Error("frame range " + RangeText(range) + " does not fit the sequence's " +
                              std::to_string(total) + " frames (0-" + std::to_string(total - 1) + ")");
    return nullptr;
  }
  *status = IoStatus::Ok();
  return std::make_unique<FrameRangeSource>(std::move(inner), range);
}

}  // namespace ccm
