// All tunables of the agent's monocular VO in one place, with units and defaults
// (mostly ORB-SLAM's monocular values). Parsed from YAML by the agent runtime only.
#pragma once

#include <string>

#include "slam_core/feature/orb_extractor.h"
#include "slam_core/map/map.h"
#include "slam_core/vo/keyframe_decision.h"
#include "slam_core/vo/local_map_bound.h"

namespace ccm {

/// Which keyframe's well-seen points (>= 3 observations) the keyframe rule measures the
/// frame's inliers against (VoOptions::kf_reference).
enum class KeyframeReference {
  kLast,           ///< the last keyframe made
  kMostCovisible,  ///< the local keyframe sharing the most points with the frame (ORB-SLAM)
  kEither,         ///< the larger count of the two: a keyframe when either would ask for one
};
/// "last", "most_covisible", "either"; false for anything else.
bool ParseKeyframeReference(const std::string& text, KeyframeReference* out);

struct VoOptions {
  OrbExtractorOptions orb;
  /// Features to extract while initializing (ORB-SLAM doubles them for mono init). Two-view
  /// matching uses only the finest pyramid level (~22 % of them): driving forward at speed
  /// (KITTI 07, 0.5-0.85 m per frame) 2000 leave 100-180 matches between neighbouring
  /// frames; the road profile takes 4000 (docs/vo.md, "Initialization on the road").
  int init_num_features = 2000;
  MapOptions map;
  LocalMapBoundOptions bound;

  // Initialization.
  int init_min_matches = 100;        ///< window matches needed to attempt two-view init
  double init_window_px = 100.0;     ///< search window around the reference keypoint
  int init_min_map_points = 100;     ///< triangulated points needed to accept init
  int init_max_frames = 40;          ///< frames before the reference frame is replaced
  double init_min_parallax_deg = 1.0;  ///< median parallax of the initial points [deg]
  /// Distant points (too little parallax to triangulate) count as explained by the two-view
  /// motion (solvers::TwoViewInitOptions::count_distant_points). Off by default: on halls and
  /// rooms it initialized on smaller baselines, with worse maps; on for roads.
  bool init_count_distant_points = false;
  /// The homography model is used only above this score ratio S_H / (S_H + S_E).
  /// ORB-SLAM uses 0.40; on the simulator's halls (floor + walls, ~1 deg parallax) the
  /// homography's two decompositions were hard to tell apart and 0.40 picked a motion
  /// 80 deg off, so the essential matrix is preferred unless the view is clearly planar.
  double init_min_homography_ratio = 0.7;
  /// Optional second chance for (near-)planar views when the essential matrix failed:
  /// the homography is accepted from this ratio on, but only with at least
  /// init_homography_min_parallax_deg. Off by default (1.0): on the simulator even 3 deg
  /// gave a wrong decomposition. Road scenes (KITTI) need init_count_distant_points
  /// instead: their "planar-looking" views are mostly distant points.
  double init_fallback_homography_ratio = 1.0;
  /// solvers::TwoViewInitOptions::min_rotation_residual_deg: the initial pair needs this
  /// much flow that no pure rotation explains (median over the inliers), measured without
  /// trusting the chosen motion. Off by default (0): 1.0 fixed the wrong starts of 4
  /// drifting flights of the tuning seeds (ATE 1.0-1.6 % -> 0.07-0.5 % of the path) but
  /// KITTI 07 from frame 0 never initializes with 0.5 or 1.0 (its right start has 0.30 deg,
  /// the wrong ones 0.16-0.39). docs/vo.md "A wrong start".
  double init_min_rotation_residual_deg = 0.0;
  /// solvers::TwoViewInitOptions::min_motion_cost_gap: the chosen two-view motion must
  /// beat every motion >= 30 deg away in translation direction by this robust cost
  /// (sigma^2 units). Wrong starts on generated halls scored -64 to -1 (their rival, the
  /// true motion, was as good or better), right ones 38-318, KITTI 07 and New Tsukuba
  /// 46-318. 0: off. docs/vo.md "A rival motion".
  double init_min_motion_cost_gap = 30.0;
  /// After this many starts refused for a rival motion (since the last map), the check is
  /// skipped: a pure plane always has one (its homography's other decomposition). The
  /// drifting hall flights needed up to 19 refusals before a clear start.
  int init_max_ambiguous_attempts = 30;
  double init_homography_min_parallax_deg = 3.0;

  // Tracking.
  double projection_radius_px = 15.0;  ///< motion-model search radius at level 0
  double local_map_radius_px = 3.0;    ///< local-map search radius at level 0 (x2.5-4 by view angle)
  int min_matches_motion_model = 20;   ///< below: retry with a doubled radius
  /// After a gap in the stream (dropped frames) the constant-velocity prediction covers the
  /// gap, up to this many of the last frame intervals. Covering only part of it is worse
  /// than a full guess: at 10, 16 dropped frames on hall3 (17 intervals) left 9 inliers of
  /// 187 matches; at 30, gaps up to 24 frames (1.2 s at 20 Hz) track at once.
  double max_motion_extrapolation = 30.0;
  int min_inliers_frame = 10;          ///< pose-only optimization inliers to accept a frame pose
  int min_inliers_local_map = 30;      ///< inliers after local-map tracking to count as tracked
  int min_inliers_after_reloc = 50;
  /// A frame the motion model could not place right after one it could (a sudden turn) is
  /// placed by the reference keyframe's points from the last pose. With this on, that lone
  /// fallback pose is weak: it makes no keyframe and the velocity after it is measured
  /// across it (Tracker::Track; gen-2043: a keyframe 1.3 m off from one such frame).
  bool weak_lone_fallback_poses = true;
  /// A tracked frame with fewer local-map inliers than this fraction of the last frame's is
  /// weak too (no keyframe from it, velocity measured across it); 0 turns the rule off.
  double weak_inlier_drop_ratio = 0.5;
  /// The keyframe rule's reference (its points seen by >= 3 keyframes against the frame's
  /// inliers). ORB-SLAM's per-frame most covisible keyframe fixed a shared-map fault but lost
  /// another agent on the tuning scenes, so the default stays the last keyframe and a stale
  /// count is caught by keyframe.inlier_drop_ratio (docs/vo.md, "Keyframes in a shared map").
  KeyframeReference kf_reference = KeyframeReference::kLast;
  int local_map_max_keyframes = 80;    ///< cap on keyframes whose points are tracked
  double min_view_cos = 0.5;           ///< points seen at > 60 deg from their mean normal skipped

  /// Keyframe decision (vo/keyframe_decision.h; YAML keys kf_*).
  KeyframeDecisionOptions keyframe;

  // Relocalization / new map segment.
  int reloc_min_matches = 30;
  /// With a vocabulary (bag-of-words relocalization): keyframe candidates tried per frame,
  /// and covisible keyframes whose points join each candidate's.
  int reloc_max_candidates = 5;
  int reloc_covisible_keyframes = 5;
  int lost_frames_before_new_segment = 40;  ///< failed relocalizations before a new segment
  int reset_if_lost_below_keyframes = 5;    ///< lost with <= this many KFs: re-initialize

  // Id counters. A restarted agent process must not reuse the ids of its previous life (the
  // server would take its new keyframes for resends of old ones): the agent runtime starts
  // them from a clock-derived base (agent_runtime/agent_runner.cc). Keyframe/point counters
  // have 48 bits, segment counters travel in 32 (idl KeyframeUpdate::segment_counter).
  uint64_t first_id_counter = 1;       ///< first keyframe and map point counter
  uint64_t first_segment_counter = 1;  ///< first map segment counter (< 2^32)

  // Local mapping.
  int triangulation_neighbours = 10;   ///< covisible KFs searched for new points
  /// Search those neighbours widest baseline first, so that a keypoint matched in several
  /// becomes a point from the best-conditioned pair (docs/vo.md "Widest baseline first").
  /// false: strongest covisibility first (ORB-SLAM's order, the default before 2026-12-07).
  bool triangulate_widest_baseline_first = true;
  int fusion_neighbours = 10;
  /// Keyframes optimized by local BA (incl. the new one). ORB-SLAM's 10 was for keyframes
  /// every 2-3 frames; with the 0.2 s spacing they are half as many, and 15 gave back the
  /// accuracy (hall3, 3 seeds: mean ATE 0.0401 m at 10, 0.0335 m at 15).
  int local_ba_window = 15;
  int local_ba_max_fixed = 30;         ///< cap on fixed periphery keyframes
  double redundant_kf_ratio = 0.9;     ///< KF culled when this share of its points is seen 3x
  /// Keyframe pairs below this baseline over the neighbour's median depth yield no new points
  /// (ORB-SLAM's test). 0.02 with min_triangulation_parallax_deg 0.3 decides parallax per pair
  /// instead of per ray: it held four agents lost in fast turns but lost three tuning agents
  /// (docs/vo.md "Parallax per pair"), so the defaults stay.
  double min_baseline_depth_ratio = 0.01;
  /// New points need at least this ray angle. Near the threshold, noisy rays that happen
  /// to look more parallel are rejected and more convergent ones kept, which biases those
  /// depths short (seen at 1.15 deg on the simulator). ORB-SLAM's 1.15 lost an agent in a
  /// 72 deg/s turn at 0.9 m/s (issue 27, seed 2117: six keyframes each matched 100-300
  /// unmapped keypoints below it); 0.8 holds it and improves most tuning agents' VO, but
  /// loses another agent and makes the fused maps worse (docs/vo.md "Points for a fast
  /// turn"), so the default stays.
  double min_triangulation_parallax_deg = 1.15;
  /// ... and at least this many times the angular noise of the coarser keypoint (its
  /// pyramid scale in pixels over the focal length). 0: off.
  double triangulation_parallax_sigmas = 0.0;

  /// Keep one small record per tracked frame and per retired keyframe for FrameTrajectory()
  /// and KeyframeTrajectory() (standalone runs, evaluation). Off for unbounded onboard runs:
  /// it grows with the flight time (about 100 B per frame).
  bool record_frame_trajectory = true;

  /// Changed ids waiting for the comm module; above this, ids of objects that left the map
  /// are dropped (nobody takes changes in standalone runs or while the server is gone).
  size_t max_pending_changes = 20000;

  std::string Validate() const;
};

}  // namespace ccm
