#include <gtest/gtest.h>

#include "slam_core/io/frame_range_source.h"

namespace ccm {
namespace {

// `n` frames, frame i stamped 1000 + 100 i ns and placed at x = i m; `known_size` false
// makes it report -1 like a live camera; `fail_at` >= 0 fails (error()) at that frame.
class CountingSource : public FrameSource {
 public:
  explicit CountingSource(int64_t n, bool known_size = true, int64_t fail_at = -1)
      : n_(n), known_size_(known_size), fail_at_(fail_at) {
    intrinsics_.fx = intrinsics_.fy = 100;
    intrinsics_.width_px = 64;
  }
  std::optional<Frame> Next() override {
    if (i_ == fail_at_) error_ = "frame " + std::to_string(i_) + " unreadable";
    if (i_ >= n_ || !error_.empty()) return std::nullopt;
    Frame f;
    f.stamp_ns = 1000 + 100 * i_;
    f.world_from_cam_gt = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(static_cast<double>(i_), 0, 0));
    ++i_;
    return f;
  }
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  int64_t size() const override { return known_size_ ? n_ : -1; }
  const std::string& error() const override { return error_; }

 private:
  int64_t n_, i_ = 0;
  bool known_size_;
  int64_t fail_at_;
  CameraIntrinsics intrinsics_;
  std::string error_;
};

std::vector<int64_t> Stamps(FrameSource* s) {
  std::vector<int64_t> out;
  while (auto f = s->Next()) {
    EXPECT_DOUBLE_EQ(f->world_from_cam_gt->translation().x(), (f->stamp_ns - 1000) / 100.0) << "ground truth kept";
    out.push_back(f->stamp_ns);
  }
  return out;
}

TEST(FrameRange, ParsesClosedAndOpenRanges) {
  IoStatus st;
  auto r = ParseFrameRange("60-159", &st);
  ASSERT_TRUE(r) << st.message();
  EXPECT_EQ(r->first, 60);
  EXPECT_EQ(r->last, 159);
  r = ParseFrameRange("70-", &st);
  ASSERT_TRUE(r) << st.message();
  EXPECT_EQ(r->first, 70);
  EXPECT_EQ(r->last, -1);
  r = ParseFrameRange("5-5", &st);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->CountIn(10), 1);
}

TEST(FrameRange, RejectsMalformedRanges) {
  for (const char* bad : {"", "60", "-99", "a-b", "1-2-3", " 1-2", "1 -2", "+1-2", "1-x", "99999999999999-"}) {
    IoStatus st;
    EXPECT_FALSE(ParseFrameRange(bad, &st)) << "'" << bad << "' accepted";
    EXPECT_NE(st.message().find("frame range"), std::string::npos) << st.message();
  }
  IoStatus st;
  EXPECT_FALSE(ParseFrameRange("159-60", &st));
  EXPECT_NE(st.message().find("before the first"), std::string::npos) << st.message();
}

TEST(FrameRangeSource, DeliversTheSliceWithItsStampsAndGroundTruth) {
  IoStatus st;
  auto s = LimitFrames(std::make_unique<CountingSource>(10), {3, 6}, &st);
  ASSERT_TRUE(s) << st.message();
  EXPECT_EQ(s->size(), 4);
  EXPECT_EQ(s->intrinsics().width_px, 64);
  EXPECT_EQ(Stamps(s.get()), (std::vector<int64_t>{1300, 1400, 1500, 1600}));
  EXPECT_FALSE(s->Next()) << "stays at the end";
  EXPECT_EQ(s->error(), "");
}

TEST(FrameRangeSource, OpenRangeRunsToTheEnd) {
  IoStatus st;
  auto s = LimitFrames(std::make_unique<CountingSource>(10), {7, -1}, &st);
  ASSERT_TRUE(s) << st.message();
  EXPECT_EQ(s->size(), 3);
  EXPECT_EQ(Stamps(s.get()), (std::vector<int64_t>{1700, 1800, 1900}));
}

TEST(FrameRangeSource, RangeOutsideAKnownSequenceIsRefused) {
  for (const FrameRange r : {FrameRange{10, -1}, FrameRange{5, 10}, FrameRange{12, 20}}) {
    IoStatus st;
    EXPECT_EQ(LimitFrames(std::make_unique<CountingSource>(10), r, &st), nullptr) << r.first << "-" << r.last;
    EXPECT_NE(st.message().find("10 frames (0-9)"), std::string::npos) << st.message();
  }
  IoStatus st = IoStatus::Error("cannot open folder x");
  EXPECT_EQ(LimitFrames(nullptr, {0, 1}, &st), nullptr);
  EXPECT_EQ(st.message(), "cannot open folder x") << "the reader's message is kept";
}

TEST(FrameRangeSource, UnknownLengthSourceThatEndsBeforeTheRangeSaysSo) {
  IoStatus st;
  auto s = LimitFrames(std::make_unique<CountingSource>(4, /*known_size=*/false), {6, 8}, &st);
  ASSERT_TRUE(s) << "length unknown: cannot be refused up front";
  EXPECT_EQ(s->size(), 3);
  EXPECT_FALSE(s->Next());
  EXPECT_NE(s->error().find("starts after the last frame (4 frames)"), std::string::npos) << s->error();
}

TEST(FrameRangeSource, ReaderErrorsPassThrough) {
  IoStatus st;
  auto s = LimitFrames(std::make_unique<CountingSource>(10, true, /*fail_at=*/4), {2, 8}, &st);
  ASSERT_TRUE(s);
  EXPECT_EQ(Stamps(s.get()).size(), 2u);
  EXPECT_EQ(s->error(), "frame 4 unreadable");
}

}  // namespace
}  // namespace ccm
