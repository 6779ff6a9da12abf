#include "slam_core/place_recognition/geometric_verification.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "slam_core/feature/keypoint_grid.h"
#include "slam_core/place_recognition/sim3_refinement.h"

namespace ccm {

namespace {

// Matches between keypoints with 3D points that fall under the same vocabulary node.
std::vector<FeatureMatch> BowMatches(const VerificationView& a, const VerificationView& b,
                                     const DescriptorMatchOptions& options) {
  MatchGroups groups;
  CommonNodeGroups(a.feature_vector, b.feature_vector, &groups.groups1, &groups.groups2);
  auto keep_with_points = [](const VerificationView& v, std::vector<int>* g) {
    g->erase(std::remove_if(g->begin(), g->end(), [&](int i) { return !v.HasPoint(i); }), g->end());
  };
  for (auto& g : groups.groups1) keep_with_points(a, &g);
  for (auto& g : groups.groups2) keep_with_points(b, &g);
  return MatchFeatures(a.features, b.features, options, &groups);
}

solvers::Sim3Result RunSim3(const VerificationView& a, const VerificationView& b,
                            const std::vector<FeatureMatch>& matches, const solvers::Sim3Options& base) {
  std::vector<Eigen::Vector3d> pa, pb;
  for (const auto& m : matches) {
    if (!a.HasPoint(m.index1) || !b.HasPoint(m.index2)) continue;
    pa.push_back(a.points_cam[m.index1]);
    pb.push_back(b.points_cam[m.index2]);
  }
  solvers::Sim3Options options = base;
  // Angular threshold at the smaller focal length: the more lenient of the two cameras.
  options.ransac.focal_px = std::min(a.camera->intrinsics().fx, b.camera->intrinsics().fx);
  return solvers::EstimateSim3(pa, pb, options);
}

// Where the 3D points of one view land in the other and which keypoint they matched.
struct Projection {
  std::vector<int> match;             // per from-keypoint: to-keypoint or -1
  std::vector<Eigen::Vector2f> uv;    // per from-keypoint: pixel in `to` (NaN if not projected)
  int projected = 0;
};

// Projects the 3D points of `from` into `to` with to_from_from and matches them to `to`'s
// keypoints by descriptor around the prediction.
Projection GuidedSearch(const VerificationView& from, const VerificationView& to,
                        const KeypointGrid& to_grid, const Sim3& to_from_from,
                        const ProjectionMatchOptions& options) {
  Projection out;
  out.match.assign(from.features.size(), -1);
  out.uv.assign(from.features.size(), Eigen::Vector2f::Constant(std::nanf("")));
  std::vector<ProjectionCandidate> candidates;
  std::vector<int> owner;
  const double focal_ratio = to.camera->intrinsics().fx / from.camera->intrinsics().fx;
  const double log_sf = std::log(to.pyramid.scale_factor);
  for (int i = 0; i < static_cast<int>(from.features.size()); ++i) {
    if (!from.HasPoint(i) || from.points_cam[i].norm() < 1e-9) continue;
    const Eigen::Vector3d p = to_from_from * from.points_cam[i];
    Eigen::Vector2d uv;
    if (p.z() <= 0.0 || !to.camera->Project(p, &uv) || !to.camera->InImage(uv)) continue;
    // Apparent size ratio (to / from) moves the expected pyramid level.
    const double ratio = focal_ratio * to_from_from.scale() * from.points_cam[i].norm() / p.norm();
    const int level = static_cast<int>(std::lround(from.features.keypoints[i].level + std::log(ratio) / log_sf));
    ProjectionCandidate c;
    c.u = static_cast<float>(uv.x());
    c.v = static_cast<float>(uv.y());
    c.level = std::clamp(level, 0, to.pyramid.num_levels - 1);
    c.descriptor = from.features.descriptors[i];
    candidates.push_back(c);
    owner.push_back(i);
    out.uv[i] = uv.cast<float>();
    ++out.projected;
  }
  for (const auto& m : MatchByProjection(candidates, to.features, to_grid, to.pyramid, options)) {
    out.match[owner[m.index1]] = m.index2;
  }
  return out;
}

// Fraction of image cells (grid x grid over `to`) holding >= min_points projected points in
// which at least min_match_ratio of them were matched: 1 if no cell has enough points. A
// true overlap is supported all over the shared view; an aliased one (an identical object
// in another place) only where that object is.
double SpatialSupport(const Projection& projection, const std::vector<bool>& matched, int width,
                      int height, const VerificationOptions& options) {
  const int g = options.support_grid;
  std::vector<int> points(g * g, 0), hits(g * g, 0);
  for (std::size_t i = 0; i < projection.uv.size(); ++i) {
    const Eigen::Vector2f& uv = projection.uv[i];
    if (!uv.allFinite()) continue;
    const int cx = std::clamp(static_cast<int>(uv.x() * g / width), 0, g - 1);
    const int cy = std::clamp(static_cast<int>(uv.y() * g / height), 0, g - 1);
    ++points[cy * g + cx];
    hits[cy * g + cx] += matched[i] ? 1 : 0;
  }
  int testable = 0, supported = 0;
  for (int c = 0; c < g * g; ++c) {
    if (points[c] < options.support_min_points) continue;
    ++testable;
    supported += hits[c] >= options.support_min_match_ratio * points[c] ? 1 : 0;
  }
  return testable > 0 ? static_cast<double>(supported) / testable : 1.0;
}

// Forward (candidate -> query) and backward (query -> candidate) projection matches that
// agree; one-directional ones count where the other side has no 3D point to project.
std::vector<FeatureMatch> ConsistentMatches(const VerificationView& cand, const VerificationView& query,
                                            const std::vector<int>& forward,
                                            const std::vector<int>& backward) {
  std::vector<FeatureMatch> out;
  std::vector<bool> query_used(query.features.size(), false);
  for (int i = 0; i < static_cast<int>(forward.size()); ++i) {
    const int j = forward[i];
    if (j < 0) continue;
    if (query.HasPoint(j) && backward[j] != i) continue;
    out.push_back(FeatureMatch{i, j, HammingDistance(cand.features.descriptors[i], query.features.descriptors[j])});
    query_used[j] = true;
  }
  for (int j = 0; j < static_cast<int>(backward.size()); ++j) {
    const int i = backward[j];
    if (i < 0 || query_used[j] || cand.HasPoint(i)) continue;
    out.push_back(FeatureMatch{i, j, HammingDistance(cand.features.descriptors[i], query.features.descriptors[j])});
  }
  return out;
}

}  // namespace

const char* VerificationStageName(VerificationStage stage) {
  static const char* kNames[kNumVerificationStages] = {"input",          "bow_matches",     "ransac", "refinement",
                                                       "guided_matches", "spatial_support", "accepted"};
  return kNames[static_cast<int>(stage)];
}

std::string VerificationView::Validate() const {
  if (!camera) return "camera missing";
  if (features.descriptors.size() != features.keypoints.size()) return "keypoints/descriptors size differ";
  if (points_cam.size() != features.size()) return "points_cam must have one entry per keypoint";
  if (pyramid.scale.size() != static_cast<std::size_t>(pyramid.num_levels)) return "pyramid not initialised";
  return {};
}

std::string VerificationOptions::Validate() const {
  std::string p = bow_match.Validate();
  if (p.empty()) p = guided.Validate();
  if (p.empty()) {
    solvers::Sim3Options s = sim3;
    s.ransac.focal_px = 1.0;  // set per call from the cameras
    p = s.Validate();
  }
  if (p.empty() && (min_bow_matches < 3 || min_inliers < 3 || min_seed_inliers < 3)) {
    p = "min_bow_matches/min_inliers/min_seed_inliers must be >= 3";
  }
  if (p.empty() && refine_rounds < 0) p = "refine_rounds must be >= 0";
  if (p.empty() && optimize) p = optimization.Validate();
  return p;
}

namespace {

// Guided search both ways under `s`: fills the consistent matches, projected count and
// spatial support of `r`.
void SearchAndScore(const VerificationView& candidate, const VerificationView& query,
                    const KeypointGrid& cand_grid, const KeypointGrid& query_grid, const Sim3& s,
                    const VerificationOptions& options, VerificationResult* r) {
  const Projection forward = GuidedSearch(candidate, query, query_grid, s, options.guided);
  const Projection backward = GuidedSearch(query, candidate, cand_grid, s.inverse(), options.guided);
  r->projected = forward.projected + backward.projected;
  r->matches = ConsistentMatches(candidate, query, forward.match, backward.match);
  r->total_matches = static_cast<int>(r->matches.size());
  std::vector<bool> cand_matched(candidate.features.size(), false), query_matched(query.features.size(), false);
  for (const auto& m : r->matches) {
    cand_matched[m.index1] = true;
    query_matched[m.index2] = true;
  }
  r->spatial_support = std::min(
      SpatialSupport(forward, cand_matched, query.camera->width(), query.camera->height(), options),
      SpatialSupport(backward, query_matched, candidate.camera->width(), candidate.camera->height(), options));
}

// Guided search, then RANSAC on the enlarged set (refine_rounds times), then the
// reprojection optimisation; ends with a guided search under the final Sim(3).
// Returns an empty string or the reason to reject.
std::string RefineAndSearch(const VerificationView& candidate, const VerificationView& query, Sim3 s,
                            const VerificationOptions& options, VerificationResult* r) {
  const KeypointGrid query_grid(query.features, query.camera->width(), query.camera->height());
  const KeypointGrid cand_grid(candidate.features, candidate.camera->width(), candidate.camera->height());
  r->final_inliers = r->ransac_inliers;
  for (int round = 0; round < options.refine_rounds; ++round) {
    SearchAndScore(candidate, query, cand_grid, query_grid, s, options, r);
    const solvers::Sim3Result refined = RunSim3(candidate, query, r->matches, options.sim3);
    if (!refined.ok()) return "Sim(3) RANSAC on the guided matches failed";
    s = refined.b_from_a;
    r->final_inliers = refined.num_inliers;
  }
  if (options.optimize) {
    if (options.refine_rounds == 0) SearchAndScore(candidate, query, cand_grid, query_grid, s, options, r);
    const Sim3RefineResult optimized = RefineSim3(candidate, query, r->matches, s, options.optimization);
    if (!optimized.ok) return "Sim(3) optimisation failed";
    s = optimized.query_from_candidate;
    r->final_inliers = optimized.num_inliers;
  }
  SearchAndScore(candidate, query, cand_grid, query_grid, s, options, r);
  r->query_from_candidate = s;
  return {};
}

}  // namespace

VerificationResult VerifyPlace(const VerificationView& candidate, const VerificationView& query,
                               const VerificationOptions& options) {
  VerificationResult r;
  std::string problem = candidate.Validate();
  if (problem.empty()) problem = query.Validate();
  if (problem.empty()) problem = options.Validate();
  if (!problem.empty()) {
    r.reason = "invalid input: " + problem;
    return r;
  }
  r.stage = VerificationStage::kBowMatches;
  const std::vector<FeatureMatch> bow = BowMatches(candidate, query, options.bow_match);
  r.bow_matches = static_cast<int>(bow.size());
  if (r.bow_matches < options.min_bow_matches) {
    r.reason = "too few BoW matches (" + std::to_string(r.bow_matches) + ")";
    return r;
  }
  r.stage = VerificationStage::kRansac;
  solvers::Sim3Options seed_options = options.sim3;
  seed_options.min_inliers = std::min(seed_options.min_inliers, options.min_seed_inliers);
  const solvers::Sim3Result sim3 = RunSim3(candidate, query, bow, seed_options);
  r.ransac_inliers = sim3.num_inliers;
  if (!sim3.ok() || sim3.num_inliers < options.min_seed_inliers) {
    r.reason = "Sim(3) RANSAC failed: " + std::string(solvers::SolverStatusName(sim3.status)) + ", " +
               std::to_string(sim3.num_inliers) + " inliers";
    return r;
  }
  r.stage = VerificationStage::kRefinement;
  r.reason = RefineAndSearch(candidate, query, sim3.b_from_a, options, &r);
  if (!r.reason.empty()) return r;
  if (r.final_inliers < options.min_inliers) {
    r.reason = "too few inliers after refinement (" + std::to_string(r.final_inliers) + ")";
    return r;
  }
  r.stage = VerificationStage::kGuidedMatches;
  if (r.total_matches < options.min_total_matches) {
    r.reason = "too few matches after guided search (" + std::to_string(r.total_matches) + ")";
    return r;
  }
  r.stage = VerificationStage::kSpatialSupport;
  if (r.spatial_support < options.min_spatial_support) {
    r.reason = "matches supported in too few image regions (" + std::to_string(r.spatial_support) + ")";
    return r;
  }
  r.stage = VerificationStage::kAccepted;
  r.accepted = true;
  return r;
}

}  // namespace ccm
