// Every tunable of the server back-end, with units and defaults (CCM-SLAM / Forster et al.
// values where the papers give them). Parsed from YAML only by the runtimes and tools.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "slam_core/map/map.h"
#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/place_recognition/geometric_verification.h"
#include "slam_core/place_recognition/keyframe_database.h"

namespace ccm {

struct FusionQueryTrace;  // place_matcher.h

struct RegistrationOptions {
  /// Forster et al.: lambda_k = lambda_{k-1} + kappa (lambda_hat - lambda_{k-1}).
  double scale_kappa = 0.05;
  /// A scale sample needs a received translation of at least this share of the keyframe's
  /// median scene depth (shorter baselines make |t_after| / |t_received| noise).
  double scale_min_baseline_depth_ratio = 0.01;
  /// Scale samples outside [1/x, x] of the current factor are outliers and ignored.
  double scale_max_step = 2.0;
  int refine_min_inliers = 15;  ///< pose refinement against the map needs this many inliers
  /// The refinement may move a keyframe from its placement by at most this share of its step
  /// from the keyframe it was placed from (the agent's VO drifts by a small share of a step;
  /// well-placed keyframes move by 0-20 % of theirs) ...
  double refine_max_step_share = 0.5;
  /// ... or by this share of its median scene depth, whichever is more (a hovering agent
  /// makes steps of nearly nothing).
  double refine_min_pull_depth_ratio = 0.05;
  /// A pull beyond that stands if the links the keyframe shares with the one it was placed
  /// from agree with it, or if at least this share of all its links does (a clear majority,
  /// where the refinement itself needs half).
  double refine_far_pull_min_share = 2.0 / 3.0;
  /// Points whose reference keyframe has not arrived wait for it, at most this many per agent.
  int max_pending_points = 20000;
  /// Own points a registered keyframe links that have not arrived: their links wait for
  /// them, for at most this many points per agent (oldest dropped).
  int max_pending_links = 100000;
  std::string Validate() const;
};

struct ServerMappingOptions {
  int fusion_neighbours = 10;     ///< covisible keyframes whose points are fused with a new keyframe
  double fusion_radius_px = 3.0;  ///< search radius at level 0 for duplicate points
  /// Local BA around a new keyframe when it got connected to keyframes of another agent or
  /// of an older part of the map (the agent already optimized its own recent window).
  bool local_ba = true;
  /// ... and only when server-side fusion gave it at least this many new associations.
  int local_ba_min_new_associations = 30;
  int local_ba_window = 10;
  int local_ba_max_fixed = 20;
  /// ORB-SLAM runs 5 robust + 10 plain iterations; the keyframe arrives already optimized
  /// by the agent, and 3 + 4 gave the same accuracy on hall3 at 3/4 of the cost.
  int local_ba_robust_iterations = 3;
  int local_ba_refine_iterations = 4;
  /// Keyframes of the same agent closer than this many ids count as "recent" (no local BA).
  int recent_keyframes = 20;
  /// Forster et al.: a keyframe within this share of the scene depth of an existing one,
  /// looking the same way, whose points all have >= 2 other observers adds nothing: it is
  /// kept only as a pose anchor. 0 disables.
  double duplicate_distance_ratio = 0.10;
  double duplicate_max_angle_deg = 10.0;
  /// > 0: after a fusion the whole overlap is welded, not just the verified pair's
  /// neighbourhood (overlap_weld.h): a keyframe of the other side closer than this share of a
  /// keyframe's median scene depth (optical axes within 30 deg) has its points fused into it.
  /// Off: at 0.5 it mends a fusion made at the end of a flight (held-out 2052 1.22x -> 0.54x
  /// its agents' VO) but over 41 generated fused maps it is neutral (geomean 0.493 both) and
  /// on real splits mixed (KITTI -6 %, New Tsukuba up to +26 %; docs/server.md "Welding").
  double overlap_weld_depth_ratio = 0.0;
  std::string Validate() const;
};

struct PlaceMatchingOptions {
  CandidateOptions candidates = [] {
    CandidateOptions o;
    o.max_results = 3;
    return o;
  }();
  VerificationOptions verification;
  /// Direct-index depth for verification: levels above the words (L=5: 3, L=6: 4); -1:
  /// depth 2 of whatever vocabulary is loaded (ORB-SLAM's choice), so a deeper default
  /// vocabulary needs no second setting.
  int vocabulary_levels_up = -1;
  /// Map-matching candidates are verified together with this many of their best covisible
  /// keyframes (MakeWindowView; ORB-SLAM3 merges with 5 in all): the query's points are
  /// matched against the whole place, not one view of it. 0: the candidate keyframe alone
  /// (CCM-SLAM). Loop candidates are always verified alone.
  int candidate_window = 4;
  /// Map matching keeps keyframes of other maps that share at least this share of the
  /// words the best of them shares with the query (ORB-SLAM's 0.8 is for loops: the same
  /// camera path). Another agent sees a place from another height and angle and shares
  /// fewer words: on unseen scenes the right keyframe scored among the best few but shared
  /// 55-75 % of the maximum, so 0.8 dropped it before verification (docs/server.md).
  double fusion_min_common_ratio = 0.6;
  /// Diagnostics (bench_fusion --recall): called on the place-recognition thread after each
  /// map-matching query with what it scored, picked and verified. Empty in production.
  std::function<void(const FusionQueryTrace&)> fusion_trace;
  /// A map needs this many keyframes before loops inside it are searched.
  int loop_min_map_keyframes = 12;
  /// Two verified detections from different query keyframes must agree (temporal and
  /// geometric consistency) before a fusion or loop is accepted: rotation and scale of the
  /// two map-level Sim(3)s within these bounds, positions within this share of the depth.
  int consistency_window_keyframes = 6;
  double consistency_max_angle_deg = 3.0;
  double consistency_max_scale_diff = 0.05;
  double consistency_max_position_ratio = 0.1;
  /// A loop's correction may rotate the query keyframe by at most this much: monocular VO
  /// drifts in scale and position, rarely by tens of degrees in rotation.
  double loop_max_correction_angle_deg = 20.0;
  /// ... nor move it by more than this share of the path flown between the loop's candidate
  /// and query keyframes (DriftPath: with two agents, the shortest route through keyframes
  /// where agents already share points, also through third agents), or the consistency
  /// share of the scene depth, if more. True loops on hall3 correct 0.2-0.6 % of that path;
  /// aliased ones in the repeated scenario 19-100 %.
  double loop_max_correction_path_ratio = 0.1;
  int min_keyframes_between_loops = 10;  ///< per map, ORB-SLAM's pause after a loop
  std::string Validate() const;
};

struct OptimizationJobOptions {
  bool global_ba_after_loop = true;
  bool global_ba_after_fusion = true;
  int global_ba_iterations = 20;
  int global_ba_threads = 2;
  opt::BaLinearSolver global_ba_solver = opt::BaLinearSolver::kAuto;
  /// A loop or fusion in a map above this many keyframes gets a global BA of the region
  /// around its keyframes only (GlobalBaOptions::max_free_keyframes; 0: always the whole
  /// map). The final BA of a run is always whole.
  int global_ba_max_free_keyframes = 0;
  /// Points seen under less parallax are held in a global BA (GlobalBaOptions::min_parallax_deg; 0: none).
  double global_ba_min_parallax_deg = 0.0;
  /// Those points move as inverse depths from their reference keyframe instead (GlobalBaOptions::low_parallax_inverse_depth).
  bool global_ba_low_parallax_inverse_depth = false;
  /// After a global BA of a map that took t seconds, the next one of that map waits
  /// factor * t (threaded runs): with many agents, loops and fusions come faster than a
  /// large map's BA, and back-to-back BAs would take the cores registration needs.
  double global_ba_pause_factor = 1.0;
  int pose_graph_iterations = 20;
  std::string Validate() const;
};

struct RedundancyOptions {
  bool enabled = true;
  double theta = 0.98;  ///< CCM-SLAM: neighbour redundant if >= theta of its points are seen by >= 3 others
  int min_map_keyframes = 20;
  std::uint64_t seed = 1;  ///< the random keyframe whose neighbours are checked
  /// Repeated passes (the map should grow with the area flown, not the time): a neighbour
  /// is also redundant when it nearly duplicates a covisible keyframe at least
  /// revisit_min_age_s older (an earlier pass, any agent): closer than revisit_distance_ratio
  /// of its median scene depth, optical axes within revisit_max_angle_deg, and at least
  /// revisit_min_covered of its points keep >= 2 other observers. The intake's near-duplicate
  /// rule cannot see these: a pass flown again arrives in its agent's drifted frame and only
  /// meets the first pass once a loop or fusion joined them. Only keyframes that their agent
  /// left behind revisit_settle_s ago or more: removing the newest ones of a pass while it is
  /// flown cost accuracy (docs/server.md "Repeated passes"). 0: off.
  double revisit_distance_ratio = 0.10;
  double revisit_max_angle_deg = 15.0;
  double revisit_min_age_s = 20.0;
  double revisit_min_covered = 0.8;
  double revisit_settle_s = 10.0;
  /// The end-of-run sweep's coverage (RedundancyRemover::SweepRevisits). Lower than the live
  /// rule's: nobody flies on, and a pass's last keyframes hold the points its agent mapped
  /// anew in its last seconds, each seen by one or two of them only (laps5: the fifth pass's
  /// last 8 keyframes covered 74-79 %, docs/server.md "At the end of a run").
  double revisit_sweep_min_covered = 0.7;
  std::string Validate() const;
};

struct ServerOptions {
  MapOptions map;
  RegistrationOptions registration;
  ServerMappingOptions mapping;
  PlaceMatchingOptions place;
  OptimizationJobOptions optimization;
  RedundancyOptions redundancy;
  int max_agents = 64;
  /// An agent that submitted nothing for this long gives its slot (queue, registration
  /// state, handler thread) to a new agent beyond max_agents; its maps stay, and if it comes
  /// back it takes a free slot again. 0: slots are never released.
  double agent_slot_release_s = 600.0;
  /// Batches waiting per agent; a batch beyond is dropped and counted (the agent resends
  /// keyframes the server never acknowledges; updates are superseded anyway), so one slow
  /// or flooding agent cannot grow the server's memory.
  int max_queued_batches_per_agent = 256;
  /// The same in memory (ApproxBatchBytes): 256 batches of a few updates are small, 256 of
  /// full keyframes (~50 kB each, more with thousands of keypoints) are not. A batch that
  /// would take a non-empty queue beyond this is dropped and counted like a full queue.
  size_t max_queued_bytes_per_agent = size_t{64} << 20;
  /// Map segments one agent may open in this server's life (each new segment id on the wire
  /// is a new server map until it fuses). An agent opens one per start and per tracking loss
  /// for good; a batch for one more is refused and counted (segments_refused), so a faulty or
  /// hostile agent cannot make the server create maps without end.
  int max_segments_per_agent = 64;
  int neighbourhood_k = 5;  ///< keyframes sent back to an agent (CCM-SLAM default 5)
  /// > 0: the neighbourhood also holds the agent's own keyframes older than this many seconds
  /// before its reference keyframe (its local map forgot them; coming back, it would map the
  /// place again; docs/server.md "Repeated passes"). 0: other agents' keyframes only (CCM-SLAM).
  /// Off by default: on generated scenes an agent whose VO drifts in scale can lock onto the
  /// scale its old keyframes come back in (one fused map 163 % apart in scale, 2026-11-29).
  double share_own_keyframes_after_s = 0.0;
  std::string Validate() const;
};

}  // namespace ccm
