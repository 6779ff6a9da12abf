// The keyframe decision on measured inputs (no images): each criterion fires on its own,
// busy mapping defers all but urgent keyframes, and nothing fires on a steady view.
#include <gtest/gtest.h>

#include "slam_core/vo/keyframe_decision.h"

namespace ccm {
namespace {

KeyframeDecisionInput Steady() {
  KeyframeDecisionInput in;
  in.frames_since_kf = 5;
  in.seconds_since_kf = 0.25;
  in.inliers = 290;
  in.reference_points = 300;
  in.coverage = 0.9;
  in.reference_coverage = 0.9;
  in.baseline_over_depth = 0.01;
  in.mapper_idle = true;
  return in;
}

KeyframeDecisionOptions AllOn() {
  KeyframeDecisionOptions o;
  o.coverage_ratio = 0.8;
  o.baseline_depth_ratio = 0.1;
  o.max_interval_s = 2.0;
  o.urgent_ratio = 0.3;
  o.urgent_inliers = 60;
  return o;
}

TEST(KeyframeDecision, SteadyViewNeedsNoKeyframe) {
  EXPECT_EQ(DecideKeyframe(AllOn(), Steady()), KeyframeReason::kNone);
  EXPECT_EQ(DecideKeyframe(KeyframeDecisionOptions{}, Steady()), KeyframeReason::kNone);
}

TEST(KeyframeDecision, EachCriterionFiresOnItsOwn) {
  const KeyframeDecisionOptions o = AllOn();
  KeyframeDecisionInput in = Steady();
  in.inliers = 170;  // 57 % of the reference's points, below 0.9
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kTrackedRatio);
  in = Steady();
  in.coverage = 0.6;  // 0.6 < 0.8 * 0.9
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kCoverage);
  in = Steady();
  in.baseline_over_depth = 0.12;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kBaseline);
  in = Steady();
  in.seconds_since_kf = 2.5;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kInterval);
  in.inliers = in.reference_points;  // nothing changed at all: hovering
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
}

TEST(KeyframeDecision, OptionalCriteriaAreOffByDefault) {
  KeyframeDecisionInput in = Steady();
  in.coverage = 0.1;
  in.baseline_over_depth = 5.0;
  in.seconds_since_kf = 100.0;
  EXPECT_EQ(DecideKeyframe(KeyframeDecisionOptions{}, in), KeyframeReason::kNone);
  in.reference_points = 32;
  in.inliers = 30;  // few, but 94 % of the reference's: no urgent keyframe on the count alone
  EXPECT_EQ(DecideKeyframe(KeyframeDecisionOptions{}, in), KeyframeReason::kNone);
}

TEST(KeyframeDecision, FarFewerPointsThanAtTheLastKeyframeNeedOne) {
  // Seed 2112 with map sharing: the reference keyframe has 44 well-seen points while the frame
  // tracks 100 (mostly another agent's), so the tracked ratio (> 1) never fires; the frame
  // tracked 239 when the last keyframe was made.
  KeyframeDecisionInput in = Steady();
  in.reference_points = 44;
  in.inliers = 130;
  in.reference_inliers = 239;
  const KeyframeDecisionOptions o;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone) << "54 % of 239: not yet";
  in.inliers = 100;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kInlierDrop);
  in.reference_inliers = 0;  // unknown (right after initialization)
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
  in.reference_inliers = 239;
  KeyframeDecisionOptions off;
  off.inlier_drop_ratio = 0;
  EXPECT_EQ(DecideKeyframe(off, in), KeyframeReason::kNone);
  in.mapper_idle = false;  // not urgent: waits for mapping like the tracked ratio
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
}

TEST(KeyframeDecision, AFastTurnGetsItsKeyframeAtOnce) {
  // Seed 2120 agent 2 at 137 deg/s, 20 Hz: two frames after a keyframe the view has turned
  // 14 deg (a quarter of its field of view) and the tracked ratio asks for a keyframe, but
  // the minimum spacing (0.2 s = 4 frames) and busy mapping would make it wait.
  KeyframeDecisionInput in = Steady();
  in.frames_since_kf = 2;
  in.seconds_since_kf = 0.1;
  in.mapper_idle = false;
  in.inliers = 240;  // 80 % of the reference's: the tracked ratio fires, the urgent one not
  KeyframeDecisionOptions o;
  o.turn_fov_share = 0.2;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone) << "no turn yet";
  in.turn_fov_share = 0.25;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kTurn);
  in.inliers = 290;  // turned, but the map still covers the view
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
  in.inliers = 240;
  o.turn_fov_share = 0;  // off
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
}

TEST(KeyframeDecision, BusyMappingDefersAllButUrgentKeyframes) {
  const KeyframeDecisionOptions o = AllOn();
  KeyframeDecisionInput in = Steady();
  in.mapper_idle = false;
  in.inliers = 150;  // 50 %: needed, not urgent
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
  in.frames_since_kf = o.max_frames;  // waited long enough: interrupt mapping
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kTrackedRatio);
  in.frames_since_kf = 1;
  in.inliers = 61;  // 20 %: about to lose the map
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kUrgent);
  in = Steady();
  in.mapper_idle = false;
  in.reference_points = 45;
  in.inliers = 44;  // few points in absolute terms, though most of the reference's
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kUrgent);
}

TEST(KeyframeDecision, NeverFromAFrameTrackingTooLittleOrTheKeyframeItself) {
  const KeyframeDecisionOptions o = AllOn();
  KeyframeDecisionInput in = Steady();
  in.inliers = o.min_inliers;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
  in = Steady();
  in.frames_since_kf = 0;
  in.inliers = 100;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
}

TEST(KeyframeDecision, MinFramesHoldsBackNonUrgentKeyframes) {
  KeyframeDecisionOptions o = AllOn();
  o.min_frames = 3;
  KeyframeDecisionInput in = Steady();
  in.frames_since_kf = 2;
  in.inliers = 150;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone);
  in.frames_since_kf = 3;
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kTrackedRatio);
}

TEST(KeyframeDecision, MinIntervalWaitsAFifthOfASecondUnlessTrackingDropsFast) {
  KeyframeDecisionOptions o;  // the defaults: 0.2 s spacing, urgent below 70 %
  ASSERT_DOUBLE_EQ(o.min_interval_s, 0.2);
  ASSERT_DOUBLE_EQ(o.urgent_ratio, 0.7);
  KeyframeDecisionInput in = Steady();
  in.inliers = 255;  // 85 %: ORB-SLAM's rule wants one, the profile waits for 0.2 s
  for (in.frames_since_kf = 1; in.frames_since_kf < 4; ++in.frames_since_kf) {
    in.seconds_since_kf = 0.05 * static_cast<double>(in.frames_since_kf);  // 20 Hz
    EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kNone) << in.frames_since_kf;
  }
  in.seconds_since_kf = 0.19999999;  // 4 frames at 20 Hz, rounded
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kTrackedRatio);
  in.frames_since_kf = 1;
  in.seconds_since_kf = 0.85;  // the first frame after 16 dropped ones
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kTrackedRatio);
  in.seconds_since_kf = 0.05;
  in.inliers = 200;  // 67 %: fast motion, the map runs out; at once
  EXPECT_EQ(DecideKeyframe(o, in), KeyframeReason::kUrgent);
}

TEST(KeyframeDecision, ValidateRejectsInconsistentOptions) {
  EXPECT_EQ(KeyframeDecisionOptions{}.Validate(), "");
  KeyframeDecisionOptions o;
  o.urgent_ratio = 0.95;  // above the tracked ratio
  EXPECT_NE(o.Validate(), "");
  o.tracked_ratio = 0.6;  // below the urgent ratio: the message says what to change
  o.urgent_ratio = 0.7;
  EXPECT_NE(o.Validate().find("kf_urgent_ratio"), std::string::npos);
  o = {};
  o.min_frames = 30;  // above max_frames
  EXPECT_NE(o.Validate(), "");
  o = {};
  o.min_interval_s = -0.1;
  EXPECT_NE(o.Validate(), "");
  o = {};
  o.coverage_ratio = 1.5;
  EXPECT_NE(o.Validate(), "");
  o = {};
  o.inlier_drop_ratio = 1.0;
  EXPECT_NE(o.Validate().find("kf_inlier_drop_ratio"), std::string::npos);
}

}  // namespace
}  // namespace ccm
