// Kidnapped agent: after flying on hall3, the camera jumps back to a place it saw more than
// 10 s earlier, still inside its local map. Tracking must be lost and relocalization (bag of
// words over the local map) must find the pose again within a few frames, close to the
// ground truth, in the same map segment (no new segment). And the milder cases: a gap of
// dropped frames must not lose tracking at all, and a frame the motion model cannot place
// in a sharp turn makes no keyframe from its fallback pose.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "slam_core/eval/alignment.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "tests/slam_core/vo/vo_sim_run.h"

namespace ccm {
namespace {

struct KidnapOutcome {
  int frames_to_relocalize = -1;  ///< frames after the jump until the first tracked one
  double max_lost_frame_ms = 0.0;  ///< slowest frame while lost (relocalization attempts)
  double position_error_m = -1.0;  ///< of that first relocalized pose, after alignment
  int segments = 0;
  int64_t relocalizations = 0;
  size_t indexed_keyframes = 0;
  std::string error;
};

// Flies `agent` of hall3 for frames [0, jump_from), then continues at frame jump_to.
KidnapOutcome FlyAndKidnap(const std::shared_ptr<const sim::Simulation>& sim, int agent, int64_t jump_from,
                           int64_t jump_to, const std::shared_ptr<const Vocabulary>& vocabulary) {
  KidnapOutcome out;
  sim::SimFrameSource before(sim, agent, 0, 1, jump_from);
  std::shared_ptr<const CameraModel> camera(MakeCamera(before.intrinsics()));
  AckAll acks;
  VoOptions options;
  AgentVo vo(static_cast<AgentId>(agent + 1), camera, options, &acks, /*synchronous_mapping=*/true, vocabulary);
  std::vector<Eigen::Vector3d> est, gt;
  while (auto f = before.Next()) {
    const TrackingResult r = vo.TrackFrame(*f);
    if (r.world_from_cam) {
      est.push_back(r.world_from_cam->translation());
      gt.push_back(f->world_from_cam_gt->translation());
    }
  }
  const auto gt_from_est = UmeyamaAlignment(est, gt, /*with_scale=*/true, &out.error);
  if (!gt_from_est) return out;
  sim::SimFrameSource after(sim, agent, jump_to, 1, 30);
  int k = 0;
  while (auto f = after.Next()) {
    const auto t0 = std::chrono::steady_clock::now();
    const TrackingResult r = vo.TrackFrame(*f);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    out.max_lost_frame_ms = std::max(out.max_lost_frame_ms, ms);
    if (r.world_from_cam) {
      out.frames_to_relocalize = k;
      out.position_error_m = ((*gt_from_est) * r.world_from_cam->translation() -
                              f->world_from_cam_gt->translation()).norm();
      break;
    }
    ++k;
  }
  const AgentVoStats stats = vo.stats();
  out.segments = stats.segments;
  out.relocalizations = stats.relocalizations;
  out.indexed_keyframes = stats.relocalization_index_size;
  return out;
}

// A sharp turn under motion blur (generated scene 2043, agent 1: a yard flown in laps at
// 10 Hz; at 51.1 s the flight reverses within 0.3 s). Flies frames [0, frames) and reports,
// for every keyframe, its position error when it was made, against the ground truth aligned
// on all tracked frames (Sim(3)).
constexpr int64_t kSharpTurnFrames = 530;  // the turn is at frame 511

struct SharpTurnOutcome {
  double worst_keyframe_error_m = -1.0;
  int64_t worst_keyframe_index = -1;
  double frame_ate_m = -1.0;
  int64_t weak_poses = 0;
  int64_t keyframes = 0;
  int64_t frames = 0, tracked = 0;
  int segments = 0;
  std::string error;
};

SharpTurnOutcome FlyThroughSharpTurn(const std::shared_ptr<const sim::Simulation>& sim, int agent, int64_t frames,
                                     const VoOptions& options) {
  SharpTurnOutcome out;
  sim::SimFrameSource source(sim, agent, 0, 1, frames);
  std::shared_ptr<const CameraModel> camera(MakeCamera(source.intrinsics()));
  AckAll acks;
  AgentVo vo(static_cast<AgentId>(agent + 1), camera, options, &acks, /*synchronous_mapping=*/true);
  std::vector<Eigen::Vector3d> est, gt;
  std::vector<std::pair<int64_t, size_t>> keyframes;  // frame index, index into est
  for (int64_t index = 0; auto f = source.Next(); ++index) {
    const TrackingResult r = vo.TrackFrame(*f);
    ++out.frames;
    if (!r.world_from_cam) continue;
    ++out.tracked;
    if (r.new_keyframe) keyframes.emplace_back(index, est.size());
    est.push_back(r.world_from_cam->translation());
    gt.push_back(f->world_from_cam_gt->translation());
  }
  const auto gt_from_est = UmeyamaAlignment(est, gt, /*with_scale=*/true, &out.error);
  if (!gt_from_est) return out;
  double sum_sq = 0.0;
  for (size_t i = 0; i < est.size(); ++i) sum_sq += ((*gt_from_est) * est[i] - gt[i]).squaredNorm();
  out.frame_ate_m = std::sqrt(sum_sq / static_cast<double>(est.size()));
  for (const auto& [index, i] : keyframes) {
    const double err = ((*gt_from_est) * est[i] - gt[i]).norm();
    if (err > out.worst_keyframe_error_m) {
      out.worst_keyframe_error_m = err;
      out.worst_keyframe_index = index;
    }
  }
  out.keyframes = static_cast<int64_t>(keyframes.size());
  out.weak_poses = vo.stats().weak_poses;
  out.segments = vo.stats().segments;
  return out;
}

void LoadHall3AndVocabulary(std::shared_ptr<const sim::Simulation>* sim, std::shared_ptr<const Vocabulary>* vocab) {
  std::string error;
  *sim = testing::LoadSimulation("hall3", &error);
  ASSERT_NE(*sim, nullptr) << error;
  auto vocabulary = LoadVocabularyFile(CCM_DEFAULT_VOCABULARY, &error);
  ASSERT_TRUE(vocabulary) << error;
  *vocab = std::make_shared<const Vocabulary>(std::move(*vocabulary));
}

TEST(VoKidnap, RelocalizesWithinFiveFramesAfterAJumpBackInsideTheLocalMap) {
  std::shared_ptr<const sim::Simulation> sim;
  std::shared_ptr<const Vocabulary> vocab;
  ASSERT_NO_FATAL_FAILURE(LoadHall3AndVocabulary(&sim, &vocab));
  // 15 s of flight, then back to where the agent was 12 s (240 frames) earlier.
  const KidnapOutcome o = FlyAndKidnap(sim, 0, 300, 60, vocab);
  ASSERT_TRUE(o.error.empty()) << o.error;
  std::printf("[kidnap] relocalized after %d frames, position error %.3f m, segments %d, slowest frame %.1f ms\n",
              o.frames_to_relocalize, o.position_error_m, o.segments, o.max_lost_frame_ms);
  ASSERT_GE(o.frames_to_relocalize, 0) << "never relocalized";
  EXPECT_GE(o.frames_to_relocalize, 1) << "a jump of 12 s must lose tracking first";
  EXPECT_LE(o.frames_to_relocalize, 5);
  EXPECT_LT(o.position_error_m, 0.05);
  EXPECT_EQ(o.segments, 1) << "relocalization, not a new segment";
  EXPECT_EQ(o.relocalizations, 1);
  EXPECT_GT(o.indexed_keyframes, 10u) << "the bag-of-words index follows the local map";
}

TEST(VoFrameGap, TracksThroughDroppedFramesWithoutRelocalizing) {
  // A camera or driver hiccup drops 8, 16 or 24 frames (0.4 / 0.8 / 1.2 s at 20 Hz). The
  // motion model predicts over the gap's duration, so the first frame after it is tracked at
  // once, at the right pose. (Predicting one frame interval, as ORB-SLAM does, tracked the
  // 8-frame gap at a pose 0.28 m off and lost the 16-frame one until relocalization; a
  // prediction capped at 10 intervals lost the 24-frame one.)
  std::shared_ptr<const sim::Simulation> sim;
  std::shared_ptr<const Vocabulary> vocab;
  ASSERT_NO_FATAL_FAILURE(LoadHall3AndVocabulary(&sim, &vocab));
  for (const int gap : {8, 16, 24}) {
    const KidnapOutcome o = FlyAndKidnap(sim, 0, 300, 300 + gap, vocab);
    ASSERT_TRUE(o.error.empty()) << o.error;
    std::printf("[gap %d frames] first tracked after %d frames, position error %.3f m, relocalizations %lld\n", gap,
                o.frames_to_relocalize, o.position_error_m, static_cast<long long>(o.relocalizations));
    EXPECT_EQ(o.frames_to_relocalize, 0) << gap << " frames dropped";
    EXPECT_EQ(o.relocalizations, 0) << gap << " frames dropped";
    EXPECT_LT(o.position_error_m, 0.05) << gap << " frames dropped";
  }
}

TEST(VoSharpTurn, ALoneFallbackPoseMakesNoKeyframe) {
  // In the turn the motion model finds 6 inliers among 210 matches; the reference keyframe's
  // points, searched from the last pose, place the frame 1.3 m off (0.15 map units: mostly a
  // translation the rotation hides) and the local map confirms it with 124 inliers, so an
  // 'urgent' keyframe was made there and the server kept it (the agent's keyframe ATE over
  // the whole flight 0.14 m instead of 0.01 m). The next frame tracks right by the motion
  // model. With the rule, that lone fallback pose makes no keyframe.
  std::string error;
  const auto sim = testing::LoadSimulation("gen:2043", &error);
  ASSERT_NE(sim, nullptr) << error;
  for (const bool weak : {false, true}) {
    VoOptions options;
    options.weak_lone_fallback_poses = weak;
    options.weak_inlier_drop_ratio = 0.0;  // the other weak-pose rule, tested below
    // The turn was recorded with the covisibility order of triangulation. With the widest
    // baseline first this flight's map differs and its frame 511 tracks by the motion model
    // (no fallback to guard against), so the rule is tested on the map that showed the fault.
    options.triangulate_widest_baseline_first = false;
    const SharpTurnOutcome o = FlyThroughSharpTurn(sim, 1, kSharpTurnFrames, options);
    ASSERT_TRUE(o.error.empty()) << o.error;
    std::printf("[sharp turn, weak poses %s] %lld keyframes, worst made %.3f m off (frame %lld); frame ATE %.4f m; "
                "weak poses %lld\n",
                weak ? "on" : "off", static_cast<long long>(o.keyframes), o.worst_keyframe_error_m,
                static_cast<long long>(o.worst_keyframe_index), o.frame_ate_m, static_cast<long long>(o.weak_poses));
    if (!weak) {
      // The premise: without the rule the turn's fallback frame is made a keyframe, far off.
      EXPECT_GT(o.worst_keyframe_error_m, 0.5);
      EXPECT_EQ(o.weak_poses, 0);
    } else {
      EXPECT_LT(o.worst_keyframe_error_m, 0.15);
      EXPECT_GE(o.weak_poses, 1);
      // The frame itself keeps its pose (1.3 m off: the frame ATE is 0.058 m either way);
      // only the map is spared it.
    }
  }
}

TEST(VoSharpTurn, ASuddenInlierDropMakesNoKeyframe) {
  // The same flight with today's triangulation order: at frame 227 the local-map inliers
  // fall from 333 to 121 for one frame, at a pose 1.7 deg off (1 s motion); the drop made
  // the frame an 'urgent' keyframe 0.19 m off. With the drop rule it makes none and the
  // next frame (371 inliers) is back on track.
  std::string error;
  const auto sim = testing::LoadSimulation("gen:2043", &error);
  ASSERT_NE(sim, nullptr) << error;
  for (const double ratio : {0.0, VoOptions{}.weak_inlier_drop_ratio}) {
    VoOptions options;
    options.weak_inlier_drop_ratio = ratio;
    const SharpTurnOutcome o = FlyThroughSharpTurn(sim, 1, 260, options);
    ASSERT_TRUE(o.error.empty()) << o.error;
    std::printf("[inlier drop, ratio %.2f] %lld keyframes, worst made %.3f m off (frame %lld); frame ATE %.4f m; "
                "weak poses %lld\n",
                ratio, static_cast<long long>(o.keyframes), o.worst_keyframe_error_m,
                static_cast<long long>(o.worst_keyframe_index), o.frame_ate_m, static_cast<long long>(o.weak_poses));
    if (ratio == 0.0) {
      EXPECT_GT(o.worst_keyframe_error_m, 0.15);  // the premise: the drop's frame is a keyframe
    } else {
      EXPECT_LT(o.worst_keyframe_error_m, 0.1);
      EXPECT_GE(o.weak_poses, 1);
    }
  }
}

TEST(VoFastTurn, LowerParallaxForNewPointsTracksThroughA72DegPerSecondTurn) {
  // gen:2117 agent 0 (VGA at 15 Hz) yaws at 72 deg/s while flying 0.9 m/s around frame 135.
  // With ORB-SLAM's 1.15 deg for new points (the default) its tracked points fell 290 -> 44
  // over six keyframes that each matched 100-300 unmapped keypoints below that angle: lost
  // at frame 140, relocalization failed and a second segment began 40 frames later. At
  // 0.8 deg it tracks through the turn (not the default: docs/vo.md "Points for a fast turn").
  std::string error;
  const auto sim = testing::LoadSimulation("gen:2117", &error);
  ASSERT_NE(sim, nullptr) << error;
  for (const double parallax : {VoOptions{}.min_triangulation_parallax_deg, 0.8}) {
    VoOptions options;
    options.min_triangulation_parallax_deg = parallax;
    const SharpTurnOutcome o = FlyThroughSharpTurn(sim, 0, 200, options);
    ASSERT_TRUE(o.error.empty()) << o.error;
    std::printf("[fast turn, new points >= %.2f deg] tracked %lld/%lld, %d segment(s), frame ATE %.4f m\n", parallax,
                static_cast<long long>(o.tracked), static_cast<long long>(o.frames), o.segments, o.frame_ate_m);
    if (parallax == 0.8) {
      EXPECT_EQ(o.segments, 1);
      EXPECT_GE(o.tracked, 190);  // the start takes ~5 frames
      EXPECT_LT(o.frame_ate_m, 0.1);
    } else {
      EXPECT_GE(o.segments, 2);  // the premise: lost in the turn
    }
  }
}

TEST(VoFastTurn, AKeyframeAtOnceInAFastTurnKeepsTracking) {
  // gen:2120 agent 2 (VGA at 20 Hz) yaws at up to 137 deg/s around frame 880. With keyframes
  // 3-4 frames apart (the 0.2 s spacing, broken only by the urgent ratio) each frame lost a
  // quarter of its points: lost at frame 894, a second segment 40 frames later. With a
  // keyframe at once after a fifth of the field of view (not the default) it tracks through.
  std::string error;
  const auto sim = testing::LoadSimulation("gen:2120", &error);
  ASSERT_NE(sim, nullptr) << error;
  for (const double share : {0.0, 0.2}) {
    VoOptions options;
    options.keyframe.turn_fov_share = share;
    const SharpTurnOutcome o = FlyThroughSharpTurn(sim, 2, 950, options);
    ASSERT_TRUE(o.error.empty()) << o.error;
    std::printf("[fast turn, kf_turn_fov_share %.2f] tracked %lld/%lld, %d segment(s), %lld keyframes, frame ATE %.4f m\n",
                share, static_cast<long long>(o.tracked), static_cast<long long>(o.frames), o.segments,
                static_cast<long long>(o.keyframes), o.frame_ate_m);
    if (share == 0.0) {
      EXPECT_GE(o.segments, 2);  // the premise: lost in the turn
    } else {
      EXPECT_EQ(o.segments, 1);
      EXPECT_GE(o.tracked, 940);  // the start takes ~10 frames
      EXPECT_LT(o.frame_ate_m, 0.2);
    }
  }
}

}  // namespace
}  // namespace ccm
