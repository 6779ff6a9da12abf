#include "slam_core/server/global_ba.h"

#include <chrono>
#include <unordered_map>

#include "slam_core/common/stopwatch.h"
#include "slam_core/optimization/bundle_adjustment.h"

namespace ccm {
namespace {

using Clock = std::chrono::steady_clock;

struct Snapshot {
  opt::BundleProblem problem;
  std::vector<KeyframeId> kf_ids;
  std::vector<MapPointId> point_ids;
  uint64_t generation = 0;
};

Snapshot TakeSnapshot(const ServerMap& smap, int min_observations) {
  Snapshot s;
  s.generation = smap.generation();
  const Map& map = smap.map();
  std::unordered_map<KeyframeId, int> index;
  std::unordered_map<const CameraModel*, int> cameras;
  std::vector<std::shared_ptr<KeyFrame>> kfs = map.keyframes();  // sorted: the oldest is the gauge
  for (const auto& kf : kfs) {
    const auto cam = cameras.emplace(&kf->camera(), static_cast<int>(s.problem.cameras.size()));
    if (cam.second) s.problem.cameras.push_back(kf->camera_ptr());
    opt::PoseBlock pose;
    pose.id = kf->id().packed();
    pose.world_from_cam = kf->world_from_cam();
    pose.fixed = s.problem.poses.empty();
    pose.camera_index = cam.first->second;
    index.emplace(kf->id(), static_cast<int>(s.problem.poses.size()));
    s.problem.poses.push_back(pose);
    s.kf_ids.push_back(kf->id());
  }
  for (const auto& mp : map.map_points()) {
    const auto obs = mp->observations();
    std::vector<opt::Observation> mine;
    for (const auto& [kf_id, idx] : obs) {
      const auto it = index.find(kf_id);
      if (it == index.end()) continue;
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
    if (static_cast<int>(mine.size()) < min_observations) continue;
    opt::PointBlock p;
    p.id = mp->id().packed();
    p.position_w = mp->position();
    s.problem.points.push_back(p);
    s.point_ids.push_back(mp->id());
    s.problem.observations.insert(s.problem.observations.end(), mine.begin(), mine.end());
  }
  return s;
}

}  // namespace

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
    snap = TakeSnapshot(*smap, options.min_observations);
  }
  r.snapshot_s = SecondsSince(t0);
  r.keyframes = static_cast<int>(snap.kf_ids.size());
  r.points = static_cast<int>(snap.point_ids.size());
  r.observations = static_cast<int>(snap.problem.observations.size());
  if (snap.problem.observations.empty() || snap.kf_ids.size() < 2) return r;

  t0 = Clock::now();
  // Gross outliers (a point far off its ray, or at the camera centre) carry no information
  // and make the first iterations chase them: leave them out; they are erased afterwards.
  std::vector<std::pair<KeyframeId, MapPointId>> gross;
  {
    std::vector<opt::Observation> kept;
    for (const opt::Observation& ob : snap.problem.observations) {
      const double chi2 = opt::ObservationChi2(snap.problem, ob);
      if (chi2 >= 0.0 && chi2 <= options.gross_outlier_chi2) {
        kept.push_back(ob);
      } else {
        gross.emplace_back(snap.kf_ids[ob.pose_index], snap.point_ids[ob.point_index]);
      }
    }
    r.observations_dropped = static_cast<int>(snap.problem.observations.size() - kept.size());
    snap.problem.observations.swap(kept);
  }
  const std::vector<opt::PoseBlock> poses_before = snap.problem.poses;
  const std::vector<opt::PointBlock> points_before = snap.problem.points;
  r.initial_rmse_px = opt::ReprojectionRmsePx(snap.problem);
  opt::BundleAdjusterOptions ba = opt::GlobalBaDefaults();
  ba.robust_iterations = options.iterations;
  ba.reject_outliers = true;
  ba.refine_iterations = options.iterations;
  ba.num_threads = options.threads;
  ba.abort = abort;
  const opt::OptimizationSummary s = opt::BundleAdjust(&snap.problem, ba);
  r.solve_s = SecondsSince(t0);
  r.iterations = s.iterations;
  r.message = s.message;
  if (!s.usable) {
    r.outcome = abort && abort->load() ? GlobalBaReport::Outcome::kAborted : GlobalBaReport::Outcome::kFailed;
    return r;
  }
  r.final_rmse_px = opt::ReprojectionRmsePx(snap.problem);

  t0 = Clock::now();
  std::unique_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  if (smap->retired() || smap->generation() != snap.generation) {
    r.outcome = GlobalBaReport::Outcome::kStale;
    return r;
  }
  Map& map = smap->map();
  std::unordered_map<KeyframeId, SE3> corrections;  // world-frame delta T_ba * T_snapshot^-1
  for (size_t k = 0; k < snap.kf_ids.size(); ++k) {
    corrections.emplace(snap.kf_ids[k], snap.problem.poses[k].world_from_cam * poses_before[k].world_from_cam.inverse());
  }
  const auto in_snapshot_kf = [&corrections](KeyframeId id) { return corrections.count(id) > 0; };
  std::vector<KeyframeId> settled;
  for (const auto& kf : map.keyframes()) {
    const KeyframeId anc = SpanningTreeAncestor(map, kf->id(), in_snapshot_kf);
    if (!anc.valid()) continue;
    if (anc != kf->id()) ++r.keyframes_added_meanwhile;
    kf->SetWorldFromCam(corrections.at(anc) * kf->world_from_cam());
    settled.push_back(kf->id());
  }
  std::unordered_map<MapPointId, size_t> in_snapshot;
  for (size_t p = 0; p < snap.point_ids.size(); ++p) in_snapshot.emplace(snap.point_ids[p], p);
  for (const auto& mp : map.map_points()) {
    const auto it = in_snapshot.find(mp->id());
    if (it != in_snapshot.end()) {
      const size_t p = it->second;
      mp->SetPosition(snap.problem.points[p].position_w + (mp->position() - points_before[p].position_w));
      continue;
    }
    const KeyframeId anc = SpanningTreeAncestor(map, mp->reference_kf(), in_snapshot_kf);
    if (anc.valid()) mp->SetPosition(corrections.at(anc) * mp->position());
  }
  for (const auto& [kf, mp] : gross) map.EraseObservation(kf, mp);
  smap->MarkSettled(settled);
  smap->BumpGeneration();
  r.write_back_s = SecondsSince(t0);
  r.outcome = GlobalBaReport::Outcome::kApplied;
  return r;
}

}  // namespace ccm
