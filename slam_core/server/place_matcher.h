// Place recognition on the server (CCM-SLAM 4.7): one bag-of-words database over the
// keyframes of all agents and maps; each new keyframe is queried twice, inside its own map
// (loop closure) and against every other map (map matching), candidates are verified
// geometrically (place_recognition/VerifyPlace) and a detection is accepted only when a
// second verified detection of the same kind, from another keyframe of the same agent within
// a few keyframes, implies the same map-level Sim(3) (temporal + geometric consistency), so
// one aliased view never fuses two maps or closes a false loop.
// Owned by the server back-end; Process() runs on the place-recognition thread only, the
// database is thread-safe for the other callers (erase after redundancy removal, fusion).
#pragma once

#include <array>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include "slam_core/place_recognition/geometric_verification.h"
#include "slam_core/place_recognition/keyframe_database.h"
#include "slam_core/place_recognition/vocabulary.h"
#include "slam_core/server/map_stack.h"
#include "slam_core/server/server_options.h"

namespace ccm {

struct PlaceDetection {
  enum class Kind { kLoop, kFusion } kind = Kind::kLoop;
  KeyframeId query, candidate;
  MapId query_map, candidate_map;
  Sim3 query_from_candidate;  ///< camera frames: p_query = S * p_candidate
  /// candidate keypoint (index1) -> query keypoint (index2), from the verification.
  std::vector<FeatureMatch> matches;
  int inliers = 0;
  KeyframeId confirmed_by;  ///< the earlier query keyframe whose detection agreed
};

struct PlaceMatcherStats {
  int64_t queries = 0;
  int64_t loop_candidates = 0, match_candidates = 0;
  int64_t verified = 0;       ///< candidates that passed geometric verification
  /// Fusion candidates by the verification stage they stopped at (VerificationStageName):
  /// tells an operator whether maps that should fuse fail on appearance or on geometry.
  std::array<int64_t, kNumVerificationStages> fusion_stopped_at{};
  int64_t inconsistent = 0;   ///< verified, but the next detection disagreed or never came
  int64_t implausible_loops = 0;  ///< verified loops whose correction exceeds the drift bound
  int64_t accepted_loops = 0, accepted_fusions = 0;
  double last_query_ms = 0.0;
  double total_query_ms = 0.0;  ///< database query + verification, summed over queries
};

/// One map-matching query as place recognition saw it (PlaceMatchingOptions::fusion_trace):
/// every keyframe of another map that shares words with the query, the candidates picked from
/// them, and where each verification stopped. A benchmark compares this with ground truth to
/// tell whether an overlap was missed by retrieval or by verification.
struct FusionQueryTrace {
  KeyframeId query;
  double min_score = 0.0;             ///< the query's bar (its least similar covisible neighbour)
  std::vector<QueryResult> scored;    ///< all keyframes of other maps sharing words
  std::vector<KeyframeId> candidates; ///< picked for verification, best group first
  struct Verification {
    KeyframeId query, candidate;      ///< query: the query or one of its neighbours (confirmation)
    VerificationStage stage = VerificationStage::kInput;
    int bow_matches = 0, ransac_inliers = 0, total_matches = 0;
  };
  std::vector<Verification> verifications;
};

class PlaceMatcher {
 public:
  PlaceMatcher(std::shared_ptr<const Vocabulary> vocabulary, const PlaceMatchingOptions& options, MapStack* stack);

  /// Adds keyframe `kf` (if still in a map) to the database and searches for a loop or an
  /// overlap; returns a detection once it is consistent.
  std::optional<PlaceDetection> Process(KeyframeId kf);

  /// Adds a keyframe's bag of words without querying (rebuilding the database after a load).
  void AddToDatabase(const KeyFrame& kf, MapId map);
  /// Database upkeep from other stages.
  void OnKeyframeErased(KeyframeId kf) {
    database_.Erase(kf);
    std::lock_guard<std::mutex> lock(nodes_mutex_);
    nodes_.erase(kf);
  }
  void OnMapsFused(MapId from, MapId into);
  void OnLoopClosed(MapId map);

  KeyframeDatabase& database() { return database_; }
  const Vocabulary& vocabulary() const { return *vocabulary_; }
  PlaceMatcherStats stats() const {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    return stats_;
  }

 private:
  struct QuerySnapshot;
  /// A keyframe as verification sees it, with where it is.
  struct View {
    KeyframeId id;
    MapId map;
    VerificationView view;
    SE3 world_from_cam;
    double depth = 1.0;
    std::vector<KeyframeId> covisible;  ///< best few, for confirmation
    /// Keypoints of the keyframe itself; a window view (MakeWindowView) has more features.
    size_t real_keypoints = 0;
  };
  static constexpr int kConfirmNeighbours = 3;
  struct Pending {
    PlaceDetection detection;
    Sim3 map_transform;  ///< fusion: lower map id <- higher map id; loop: corrected <- current
    Eigen::Vector3d probe = Eigen::Vector3d::Zero();  ///< point (source frame) where two transforms are compared
    double depth = 1.0;                               ///< scene depth in the target frame (tolerance unit)
    int64_t query_count = 0;  ///< loops: the agent's queries so far; fusions: everyone's
  };
  std::optional<PlaceDetection> TryCandidates(const QuerySnapshot& q, const std::vector<PlaceCandidate>& candidates,
                                              PlaceDetection::Kind kind);
  std::optional<PlaceDetection> CheckConsistency(const Pending& fresh);
  /// `window`: the keyframe with its best covisible neighbours (options_.candidate_window).
  std::optional<View> Snapshot(KeyframeId id, bool window = false) const;
  std::optional<Pending> Verify(const View& query, const View& candidate, PlaceDetection::Kind kind);
  std::optional<PlaceDetection> ConfirmWithNeighbours(const View& q, const View& c, const Pending& first);
  bool Agree(const Pending& a, const Pending& b) const;
  /// Vocabulary nodes of a keyframe's keypoints: kept from its query, computed if missing.
  std::vector<NodeId> NodesOf(const KeyFrame& kf) const;
  void KeepNodes(KeyframeId kf, const FeatureVector& features, size_t num_features);
  /// DriftPath between two keyframes of `to`'s map (nullopt: no map, or two agents no chain
  /// of junctions joins).
  std::optional<double> DriftPathBetween(KeyframeId from, KeyframeId to) const;
  void Bump(int64_t PlaceMatcherStats::*field, int64_t n = 1) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.*field += n;
  }

  std::shared_ptr<const Vocabulary> vocabulary_;
  const PlaceMatchingOptions options_;
  MapStack* stack_;
  KeyframeDatabase database_;
  /// Pending detections: loops by (kind, agent, map), fusions by (kind, lower map, higher map).
  std::map<std::tuple<int, MapId, MapId>, Pending> pending_;
  std::map<AgentId, int64_t> agent_queries_;
  std::map<MapId, int64_t> keyframes_since_loop_;
  FusionQueryTrace* trace_ = nullptr;  ///< set during a traced map-matching query (PR thread only)
  /// Direct index per keyframe as one node per keypoint (4 bytes each): verification views
  /// of candidates and their windows are built from these instead of a vocabulary descent.
  mutable std::mutex nodes_mutex_;  // leaf; guards nodes_ (erased from other stages)
  mutable std::unordered_map<KeyframeId, std::vector<NodeId>> nodes_;
  mutable std::mutex stats_mutex_;  // leaf; guards stats_ (written by Process, read by anyone)
  PlaceMatcherStats stats_;
};

}  // namespace ccm
