// Scores a collaborative replay of a simulated scene against the simulator's ground truth:
// which overlapping pairs of agents fused and how long after they first saw a common place,
// whether each fusion and loop was right (its verified relative pose against the true one),
// each fused map's joint ATE against its agents' own VO, the scale agreement of the agents'
// parts, and every agent's VO. Used by bench_fusion (a table over many generated scenes) and
// by tests that check one scene.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "tests/sim/overlap_truth.h"
#include "tests/sim/simulation.h"
#include "tools/replay/replay_session.h"

namespace ccm::bench {

struct PairScore {
  sim::PairTruth truth;
  bool fused = false;
  double fused_at_s = -1.0;        ///< flight time of the fusion that joined them (data time)
  double seconds_to_fusion = -1.0; ///< from the first qualifying overlap (>= 0)
};

/// A loop or fusion compared with the ground-truth relative pose of its two keyframes.
struct DetectionCheck {
  ServerEvent event;
  double rotation_error_deg = 0.0;
  double direction_error_deg = 0.0;  ///< of the translation, when the keyframes are >= 0.3 m apart
  double baseline_m = 0.0;           ///< true distance between the two keyframes' centres
  /// The same distance as the detection estimated it, in metres by the query agent's local VO
  /// scale; NaN where that scale is unknown. With baseline_m it tells whether a large
  /// direction error comes with a wrong distance or only a short baseline.
  double estimated_baseline_m = std::numeric_limits<double>::quiet_NaN();
  double view_share = 0.0;           ///< ground-truth co-visibility of the two keyframes (min share)
  /// The same against the candidate's neighbourhood: the best share over the candidate
  /// agent's views within 2 s of the candidate keyframe. A fusion is verified against the
  /// candidate and its covisible window (PlaceMatchingOptions::candidate_window), so the
  /// query may have seen the place mostly through the candidate's neighbours.
  double window_view_share = 0.0;
  /// The similarity's scale against the ratio of the two agents' VO scales around the two
  /// keyframes (est / true - 1; NaN where a VO segment is too short). Exact for maps that no
  /// earlier fusion or loop rescaled, an indication otherwise.
  double scale_error = std::numeric_limits<double>::quiet_NaN();
  bool wrong = false;                ///< rotation > 10 deg, direction > 30 deg, or window_view_share < 5 %
};

struct MapScore {
  MapId id;
  std::vector<int> agents;           ///< agent indices with keyframes in it
  size_t keyframes = 0;
  double joint_ate_m = -1.0;         ///< all its keyframes, one Sim(3)
  double mean_standalone_ate_m = -1.0;  ///< its agents' own VO, mean of RMSEs
  double scale_spread = 0.0;         ///< max / min of the agents' own alignment scales, minus 1
  /// Per agent in `agents`: ATE under its own alignment, under the map's joint one, and the
  /// scale of its own alignment (metres per map unit).
  std::vector<double> own_ate_m, joint_ate_per_agent_m, agent_scale;
};

struct AgentScore {
  std::string name;
  double path_m = 0.0;
  double tracked_share = 0.0;
  int segments = 0;
  int64_t relocalizations = 0;
  double vo_ate_m = -1.0;            ///< VO keyframes, each segment aligned on its own
  /// Ground-truth path its own VO keyframes span (chords between consecutive ones, summed over
  /// segments). With map sharing an agent that tracks other agents' keyframes makes few of
  /// its own, so its VO ATE covers only part of its flight: the share is taken of that part.
  double vo_path_m = 0.0;
  double vo_ate_path_pct = -1.0;     ///< vo_ate_m / vo_path_m * 100 (path_m if that is unknown)
  /// Scale drift of its longest segment over 5 m windows of path (largest / smallest window
  /// scale - 1; -1: shorter than two windows) and the first window's scale (its own
  /// alignment = 1): far from 1 when the scale moved right after initialization.
  double vo_scale_drift = -1.0, vo_first_window_scale = -1.0;
  bool revisits = false;
  int loops = 0;                     ///< loops the server closed on its keyframes
  /// Pairs of its own keyframes >= the truth's revisit gap apart that share points in a server
  /// map (RevisitLink), split by ground truth: true ones saw a common place, false ones did not
  /// (a wrong association). A revisit is joined when a true link exists: the map holds the
  /// place once, by a loop or because the agent tracked its earlier points (a loop is only
  /// looked for between keyframes that share nothing yet).
  int true_revisit_links = 0, false_revisit_links = 0;
  bool revisit_joined = false;
  /// Its own VO keyframes from the truth's first revisit on (-1: no revisit). 0 while it
  /// tracks: it flew every revisit localized in the map it had (its own earlier keyframes or
  /// other agents' that the server sent), so no keyframe of its own exists there to join or
  /// to close a loop with, and none is needed.
  int keyframes_from_revisit = -1;
  /// A loop, a true revisit link, or every revisit flown in the map it had (above, tracking
  /// >= 99 % of its frames).
  bool revisit_held() const {
    return revisits && (loops > 0 || revisit_joined || (keyframes_from_revisit == 0 && tracked_share >= 0.99));
  }
  size_t server_keyframes = 0, anchored_keyframes = 0;  ///< registered on the server / of those anchored
};

struct SceneScore {
  std::vector<PairScore> pairs;
  std::vector<DetectionCheck> fusions, loops;
  std::vector<MapScore> maps;
  std::vector<AgentScore> agents;
  int qualifying_pairs = 0, qualifying_fused = 0;
  int false_fusions = 0, false_loops = 0;
  /// Worst fused map: joint ATE / mean standalone ATE (-1 without a fused map).
  double worst_joint_ratio = -1.0;
  double worst_scale_spread = 0.0;
};

SceneScore ScoreScene(const sim::Simulation& sim, const sim::OverlapTruth& truth, const report::RunResult& result);

}  // namespace ccm::bench
