#include "slam_core/server/global_ba.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "slam_core/common/stopwatch.h"

namespace ccm {
namespace {

using Clock = std::chrono::steady_clock;

struct Snapshot {
  opt::BundleProblem problem;
  std::vector<KeyframeId> kf_ids;
  std::vector<MapPointId> point_ids;
  std::vector<KeyframeId> untouched;  ///< in the map at the snapshot but not in the problem (a region's outside)
  size_t free_keyframes = 0;
  int points_low_parallax = 0;
  uint64_t generation = 0;
};

// `region`: the free keyframes (null: all, the oldest fixed as the gauge); keyframes that
// see their points enter fixed.
Snapshot TakeSnapshot(const ServerMap& smap, const GlobalBaOptions& options,
                      const std::unordered_set<KeyframeId>* region) {
  Snapshot s;
  s.generation = smap.generation();
  const Map& map = smap.map();
  std::unordered_map<KeyframeId, int> index;
  std::unordered_map<const CameraModel*, int> cameras;
  std::vector<std::shared_ptr<KeyFrame>> kfs;  // problem pose k is kfs[k]
  const auto add_pose = [&](const std::shared_ptr<KeyFrame>& kf, bool fixed) {
    const auto cam = cameras.emplace(&kf->camera(), static_cast<int>(s.problem.cameras.size()));
    if (cam.second) s.problem.cameras.push_back(kf->camera_ptr());
    opt::PoseBlock pose;
    pose.id = kf->id().packed();
    pose.world_from_cam = kf->world_from_cam();
    pose.fixed = fixed;
    pose.camera_index = cam.first->second;
    const int k = static_cast<int>(s.problem.poses.size());
    index.emplace(kf->id(), k);
    s.problem.poses.push_back(pose);
    s.kf_ids.push_back(kf->id());
    kfs.push_back(kf);
    return k;
  };
  for (const auto& kf : map.keyframes()) {  // sorted: the oldest is the gauge
    if (!region) {
      add_pose(kf, s.problem.poses.empty());
    } else if (region->count(kf->id())) {
      add_pose(kf, false);
    }
  }
  s.free_keyframes = s.kf_ids.size();
  for (const auto& mp : map.map_points()) {
    const auto obs = mp->observations();
    if (region && std::none_of(obs.begin(), obs.end(), [&](const auto& o) { return region->count(o.first) > 0; })) {
      continue;
    }
    std::vector<opt::Observation> mine;
    for (const auto& [kf_id, idx] : obs) {
      auto it = index.find(kf_id);
      if (it == index.end()) {
        const auto periphery = region ? map.keyframe(kf_id) : nullptr;
        if (!periphery) continue;
        it = index.emplace(kf_id, add_pose(periphery, true)).first;
      }
      const KeyFrame& kf = *kfs[it->second];
      if (idx < 0 || static_cast<size_t>(idx) >= kf.num_keypoints()) continue;
      const Keypoint& k = kf.features().keypoints[idx];
      opt::Observation o;
      o.pose_index = it->second;
      o.point_index = static_cast<int>(s.problem.points.size());
      o.uv_px = Eigen::Vector2d(k.u, k.v);
      o.sigma_px = kf.pyramid().scale[k.level];
      mine.push_back(o);
    }
    if (static_cast<int>(mine.size()) < options.min_observations) continue;
    bool low_parallax = false;
    s.problem.points.push_back(GlobalBaPointBlock(*mp, mine, kfs, options, &low_parallax));
    s.points_low_parallax += low_parallax ? 1 : 0;
    s.point_ids.push_back(mp->id());
    s.problem.observations.insert(s.problem.observations.end(), mine.begin(), mine.end());
  }
  if (region) {
    for (const auto& kf : map.keyframes()) {
      if (!index.count(kf->id())) s.untouched.push_back(kf->id());
    }
  }
  return s;
}

// How much the BA stretched the map around keyframe `root` (1: not at all, or not known):
// the summed distances to its best covisible keyframes after over before. An anchor's offset
// from its base is in map units and must follow, or it lands off by (stretch - 1) x its
// offset: the monocular scale of an agent's part settles in the BA after its loops and
// fusions (hall3 demo: parts 2-4 % shorter, anchors 2 cm off their neighbours).
double LocalStretch(const Map& map, KeyframeId root, const std::unordered_map<KeyframeId, size_t>& index,
                    const std::vector<opt::PoseBlock>& before, const std::vector<opt::PoseBlock>& after) {
  constexpr int kNeighbours = 10;
  constexpr int kMinNeighbours = 3;
  const auto kf = map.keyframe(root);
  const auto r = index.find(root);
  if (!kf || r == index.end()) return 1.0;
  double sum_before = 0.0, sum_after = 0.0;
  int used = 0;
  for (const KeyframeId n : kf->BestCovisible(kNeighbours)) {
    const auto i = index.find(n);
    if (i == index.end()) continue;
    sum_before += (before[i->second].world_from_cam.translation() - before[r->second].world_from_cam.translation()).norm();
    sum_after += (after[i->second].world_from_cam.translation() - after[r->second].world_from_cam.translation()).norm();
    ++used;
  }
  if (used < kMinNeighbours || !(sum_before > 0.0)) return 1.0;
  const double stretch = sum_after / sum_before;
  return stretch > 0.5 && stretch < 2.0 ? stretch : 1.0;  // beyond: a broken problem, not a stretch
}

}  // namespace

opt::BundleAdjusterOptions GlobalBaSolverOptions(const GlobalBaOptions& options, const std::atomic<bool>* abort) {
  opt::BundleAdjusterOptions ba = opt::GlobalBaDefaults();
  ba.robust_iterations = options.iterations;
  ba.reject_outliers = true;
  ba.refine_iterations = options.iterations;
  ba.num_threads = options.threads;
  ba.linear_solver = options.linear_solver;
  ba.abort = abort;
  return ba;
}

opt::PointBlock GlobalBaPointBlock(const MapPoint& mp, const std::vector<opt::Observation>& obs,
                                   const std::vector<std::shared_ptr<KeyFrame>>& keyframes,
                                   const GlobalBaOptions& options, bool* low_parallax) {
  *low_parallax = false;
  if (options.min_parallax_deg > 0.0) {  // off by default: no per-point work under the map lock then
    std::vector<Eigen::Vector3d> centres;
    for (const opt::Observation& o : obs) centres.push_back(keyframes[o.pose_index]->world_from_cam().translation());
    *low_parallax = !HasParallax(mp.position(), centres, options.min_parallax_deg);
  }
  opt::PointBlock p;
  p.id = mp.id().packed();
  p.position_w = mp.position();
  p.fixed = *low_parallax && !options.low_parallax_inverse_depth;
  if (*low_parallax && options.low_parallax_inverse_depth && !obs.empty()) {
    p.anchor_pose = obs.front().pose_index;
    for (const opt::Observation& o : obs) {
      if (keyframes[o.pose_index]->id() == mp.reference_kf()) p.anchor_pose = o.pose_index;
    }
  }
  return p;
}

bool HasParallax(const Eigen::Vector3d& point_w, const std::vector<Eigen::Vector3d>& centres_w, double min_deg) {
  if (!(min_deg > 0.0)) return true;
  const double max_cos = std::cos(min_deg * M_PI / 180.0);
  std::vector<Eigen::Vector3d> rays;
  for (const Eigen::Vector3d& c : centres_w) {
    const Eigen::Vector3d ray = point_w - c;
    if (!(ray.norm() > 0.0)) continue;
    const Eigen::Vector3d unit = ray.normalized();
    for (const Eigen::Vector3d& other : rays) {
      if (unit.dot(other) < max_cos) return true;
    }
    rays.push_back(unit);
  }
  return false;
}

std::vector<size_t> DropGrossOutliers(opt::BundleProblem* problem, const GlobalBaOptions& options) {
  // Gross outliers (a point far off its ray, or at the camera centre) carry no information
  // and make the first iterations chase them: leave them out (the caller erases them).
  std::vector<size_t> dropped;
  std::vector<opt::Observation> kept;
  for (size_t i = 0; i < problem->observations.size(); ++i) {
    const opt::Observation& ob = problem->observations[i];
    const double chi2 = opt::ObservationChi2(*problem, ob);
    if (chi2 >= 0.0 && chi2 <= options.gross_outlier_chi2) {
      kept.push_back(ob);
    } else {
      dropped.push_back(i);
    }
  }
  problem->observations.swap(kept);
  return dropped;
}

std::unordered_set<KeyframeId> CovisibleRegion(const Map& map, const std::vector<KeyframeId>& seeds, size_t max_free) {
  std::unordered_set<KeyframeId> region;
  std::vector<KeyframeId> hop;
  for (const KeyframeId id : seeds) {
    if (region.size() < max_free && map.keyframe(id) && region.insert(id).second) hop.push_back(id);
  }
  while (!hop.empty() && region.size() < max_free) {
    std::vector<KeyframeId> next;
    for (const KeyframeId id : hop) {
      const auto kf = map.keyframe(id);
      if (!kf) continue;
      for (const KeyframeId n : kf->BestCovisible(std::numeric_limits<int>::max())) {  // strongest first
        if (region.size() >= max_free) break;
        if (map.keyframe(n) && region.insert(n).second) next.push_back(n);
      }
    }
    hop.swap(next);
  }
  return region;
}

const char* GlobalBaOutcomeName(GlobalBaReport::Outcome outcome) {
  switch (outcome) {
    case GlobalBaReport::Outcome::kApplied: return "applied";
    case GlobalBaReport::Outcome::kAborted: return "aborted";
    case GlobalBaReport::Outcome::kStale: return "stale";
    case GlobalBaReport::Outcome::kFailed: return "failed";
    case GlobalBaReport::Outcome::kEmpty: return "empty";
  }
  return "?";
}

GlobalBaReport RunGlobalBundleAdjustment(const std::shared_ptr<ServerMap>& smap, const GlobalBaOptions& options,
                                         const std::atomic<bool>* abort) {
  GlobalBaReport r;
  r.map = smap->id();
  auto t0 = Clock::now();
  Snapshot snap;
  {
    std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
    if (smap->retired()) {
      r.outcome = GlobalBaReport::Outcome::kStale;
      return r;
    }
    std::unordered_set<KeyframeId> region;
    const bool regional = options.max_free_keyframes > 0 && !options.region_seeds.empty() &&
                          smap->map().num_keyframes() > static_cast<size_t>(options.max_free_keyframes);
    if (regional) region = CovisibleRegion(smap->map(), options.region_seeds, options.max_free_keyframes);
    snap = TakeSnapshot(*smap, options, regional && !region.empty() ? &region : nullptr);
  }
  r.snapshot_s = SecondsSince(t0);
  r.keyframes = static_cast<int>(snap.kf_ids.size());
  r.free_keyframes = static_cast<int>(snap.free_keyframes);
  r.points = static_cast<int>(snap.point_ids.size());
  r.points_low_parallax = snap.points_low_parallax;
  r.observations = static_cast<int>(snap.problem.observations.size());
  if (snap.problem.observations.empty() || snap.kf_ids.size() < 2) return r;

  t0 = Clock::now();
  std::vector<std::pair<KeyframeId, MapPointId>> gross;
  {
    const std::vector<opt::Observation> all = snap.problem.observations;
    for (const size_t i : DropGrossOutliers(&snap.problem, options)) {
      gross.emplace_back(snap.kf_ids[all[i].pose_index], snap.point_ids[all[i].point_index]);
    }
    r.observations_dropped = static_cast<int>(gross.size());
  }
  const std::vector<opt::PoseBlock> poses_before = snap.problem.poses;
  const std::vector<opt::PointBlock> points_before = snap.problem.points;
  r.initial_rmse_px = opt::ReprojectionRmsePx(snap.problem);
  const opt::OptimizationSummary s = opt::BundleAdjust(&snap.problem, GlobalBaSolverOptions(options, abort));
  r.solve_s = SecondsSince(t0);
  r.iterations = s.iterations;
  r.rejected_steps = s.rejected_steps;
  r.message = s.message;
  if (!s.usable) {
    r.outcome = abort && abort->load() ? GlobalBaReport::Outcome::kAborted : GlobalBaReport::Outcome::kFailed;
    return r;
  }
  r.final_rmse_px = opt::ReprojectionRmsePx(snap.problem);
  r.final_inlier_rmse_px = opt::ReprojectionRmsePx(snap.problem, &s.inlier);
  r.final_inliers = s.num_inliers;

  t0 = Clock::now();
  std::unique_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  if (smap->retired() || smap->generation() != snap.generation) {
    r.outcome = GlobalBaReport::Outcome::kStale;
    return r;
  }
  Map& map = smap->map();
  std::unordered_map<KeyframeId, SE3> corrections;  // world-frame delta T_ba * T_snapshot^-1
  std::unordered_set<KeyframeId> optimized;  // free in the problem
  for (size_t k = 0; k < snap.kf_ids.size(); ++k) {
    const bool fixed = snap.problem.poses[k].fixed;  // the gauge, or a region's periphery: exactly unmoved
    corrections.emplace(snap.kf_ids[k],
                        fixed ? SE3() : snap.problem.poses[k].world_from_cam * poses_before[k].world_from_cam.inverse());
    if (!fixed || k == 0) optimized.insert(snap.kf_ids[k]);
  }
  for (const KeyframeId id : snap.untouched) corrections.emplace(id, SE3());  // outside the region: stays
  const auto in_snapshot_kf = [&corrections](KeyframeId id) { return corrections.count(id) > 0; };
  std::vector<KeyframeId> settled;
  for (const auto& kf : map.keyframes()) {
    const KeyframeId anc = SpanningTreeAncestor(map, kf->id(), in_snapshot_kf);
    if (!anc.valid()) continue;
    if (anc != kf->id()) ++r.keyframes_added_meanwhile;
    kf->SetWorldFromCam(corrections.at(anc) * kf->world_from_cam());
    if (optimized.count(anc)) settled.push_back(kf->id());
  }
  std::unordered_map<MapPointId, size_t> in_snapshot;
  for (size_t p = 0; p < snap.point_ids.size(); ++p) in_snapshot.emplace(snap.point_ids[p], p);
  for (const auto& mp : map.map_points()) {
    const auto it = in_snapshot.find(mp->id());
    if (it != in_snapshot.end() && !snap.problem.points[it->second].fixed) {  // held ones follow their keyframe
      const size_t p = it->second;
      mp->SetPosition(snap.problem.points[p].position_w + (mp->position() - points_before[p].position_w));
      continue;
    }
    const KeyframeId anc = SpanningTreeAncestor(map, mp->reference_kf(), in_snapshot_kf);
    if (anc.valid()) mp->SetPosition(corrections.at(anc) * mp->position());
  }
  for (const auto& [kf, mp] : gross) map.EraseObservation(kf, mp);
  std::unordered_map<KeyframeId, size_t> pose_index;
  for (size_t k = 0; k < snap.kf_ids.size(); ++k) pose_index.emplace(snap.kf_ids[k], k);
  std::unordered_map<KeyframeId, double> stretch;  // per anchor root, computed once
  smap->RescaleAnchors([&](KeyframeId root) {
    const auto it = stretch.find(root);
    if (it != stretch.end()) return it->second;
    return stretch[root] = LocalStretch(map, root, pose_index, poses_before, snap.problem.poses);
  });
  smap->MarkSettled(settled);
  smap->BumpGeneration();
  r.write_back_s = SecondsSince(t0);
  r.outcome = GlobalBaReport::Outcome::kApplied;
  return r;
}

}  // namespace ccm
