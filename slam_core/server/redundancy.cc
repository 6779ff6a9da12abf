#include "slam_core/server/redundancy.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <shared_mutex>

#include "slam_core/map/near_duplicate.h"
#include "slam_core/map_ops/map_bundle_adjustment.h"

namespace ccm {
namespace {

// The pose an anchor keeps: the keyframe's, refined against its points (pose only). A loop
// closure or fusion moves a neighbourhood by one Sim(3) and fuses its points with the earlier
// pass's; until the next global BA its keyframes sit a few centimetres off the points they now
// share, and that is exactly when they first count as revisits. Anchored then, a keyframe
// kept that offset for good (hall3 demo: 2-5 cm, once 22 cm, where an agent's second pass
// began). nullopt: most links disagree with every pose (the keyframe stays for the BA).
std::optional<SE3> AnchorPose(const Map& map, const KeyFrame& kf) {
  constexpr int kMinLinks = 15;  // fewer: too few to judge, the pose as it is
  const std::vector<opt::PointObservation> obs = LinkedPointObservations(map, kf);
  SE3 pose = kf.world_from_cam();
  if (static_cast<int>(obs.size()) < kMinLinks) return pose;
  const opt::OptimizationSummary s = opt::OptimizePose(kf.camera(), obs, &pose);
  if (!s.usable || 2 * s.num_inliers < static_cast<int>(obs.size())) return std::nullopt;
  return pose;
}

}  // namespace

bool RedundancyRemover::IsRedundant(const Map& map, const KeyFrame& kf) const {
  int valid = 0, redundant = 0;
  const auto mps = kf.map_points();
  for (size_t i = 0; i < mps.size(); ++i) {
    if (!mps[i].valid()) continue;
    const auto mp = map.map_point(mps[i]);
    if (!mp || mp->bad()) continue;
    ++valid;
    const int level = kf.features().keypoints[i].level;
    int others = 0;
    for (const auto& [okf, oidx] : mp->observations()) {
      if (okf == kf.id()) continue;
      const auto o = map.keyframe(okf);
      if (o && static_cast<size_t>(oidx) < o->num_keypoints() && o->features().keypoints[oidx].level <= level + 1) {
        ++others;
      }
      if (others >= 3) break;
    }
    redundant += others >= 3;
  }
  return valid > 0 && redundant >= options_.theta * valid;
}

KeyframeId RedundancyRemover::RevisitOf(const Map& map, const KeyFrame& kf, double min_covered) const {
  if (!(options_.revisit_distance_ratio > 0.0)) return KeyframeId::Invalid();
  NearDuplicateRule rule;
  rule.distance_ratio = options_.revisit_distance_ratio;
  rule.max_angle_deg = options_.revisit_max_angle_deg;
  rule.min_covered = min_covered;
  rule.candidates = -1;  // an earlier pass shares fewer points than the keyframes flown just before
  const int64_t min_age_ns = std::llround(options_.revisit_min_age_s * 1e9);
  return NearDuplicateOf(map, kf, rule, [&](KeyframeId id) {
    const auto b = map.keyframe(id);
    return b && b->stamp_ns() + min_age_ns <= kf.stamp_ns();
  });
}

RedundancyStep RedundancyRemover::Step(ServerMap* smap, const std::vector<KeyframeId>& protected_ids) {
  RedundancyStep step;
  Map& map = smap->map();
  const auto kfs = map.keyframes();
  if (kfs.size() < 3) return step;
  const KeyframeId oldest = kfs.front()->id();
  // Where each agent is now (its handlers' newest keyframes): the revisit rule leaves the
  // keyframes it flew in the last revisit_settle_s alone.
  std::map<AgentId, int64_t> newest_ns;
  for (const KeyframeId id : protected_ids) {
    // The newest keyframe may have stayed only as an anchor (a near-duplicate at intake).
    const auto k = map.keyframe(id);
    const auto anchor = k ? std::nullopt : smap->Anchor(id);
    if (k || anchor) newest_ns[id.agent()] = std::max(newest_ns[id.agent()], k ? k->stamp_ns() : anchor->stamp_ns);
  }
  const int64_t settle_ns = std::llround(options_.revisit_settle_s * 1e9);
  const auto settled = [&](const KeyFrame& k) {
    const auto it = newest_ns.find(k.id().agent());
    return it == newest_ns.end() || k.stamp_ns() + settle_ns <= it->second;
  };
  const auto pick = kfs[std::uniform_int_distribution<size_t>(0, kfs.size() - 1)(rng_)];
  step.checked = pick->id();
  for (const KeyframeId nid : pick->BestCovisible(-1)) {
    const auto n = map.keyframe(nid);
    if (!n || !Removable(*n, oldest, protected_ids)) continue;
    // Held, not looked up again: a handler's server mapping may erase it meanwhile.
    std::shared_ptr<KeyFrame> base;
    if (IsRedundant(map, *n)) {
      // Anchor to the strongest neighbour that stays.
      for (const KeyframeId b : n->BestCovisible(-1)) {
        if (b == nid) continue;
        if ((base = map.keyframe(b))) break;
      }
    } else if (settled(*n)) {
      // The earlier pass's keyframe it duplicates, if any.
      if (const KeyframeId earlier = RevisitOf(map, *n, options_.revisit_min_covered); earlier.valid()) {
        base = map.keyframe(earlier);
      }
    }
    if (base) MakeAnchor(smap, *n, *base, &step);
  }
  return step;
}

RedundancyStep RedundancyRemover::SweepRevisits(ServerMap* smap,
                                                const std::vector<KeyframeId>& protected_ids) const {
  RedundancyStep step;
  Map& map = smap->map();
  const auto kfs = map.keyframes();
  if (!options_.enabled || kfs.size() < 3 || !(options_.revisit_distance_ratio > 0.0)) return step;
  const KeyframeId oldest = kfs.front()->id();
  // Oldest first by stamp: a third pass then finds the first one, the second already gone.
  auto order = kfs;
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a->stamp_ns() < b->stamp_ns(); });
  for (const auto& n : order) {
    // Erased meanwhile (a handler's server mapping) or not removable.
    if (!map.keyframe(n->id()) || !Removable(*n, oldest, protected_ids)) continue;
    const KeyframeId earlier = RevisitOf(map, *n, options_.revisit_sweep_min_covered);
    if (!earlier.valid()) continue;
    if (const auto base = map.keyframe(earlier)) MakeAnchor(smap, *n, *base, &step);
  }
  return step;
}

bool RedundancyRemover::Removable(const KeyFrame& kf, KeyframeId oldest, const std::vector<KeyframeId>& protected_ids) {
  if (kf.id() == oldest || kf.bad() || !kf.loop_edges().empty()) return false;
  return std::find(protected_ids.begin(), protected_ids.end(), kf.id()) == protected_ids.end();
}

void RedundancyRemover::MakeAnchor(ServerMap* smap, const KeyFrame& kf, const KeyFrame& base, RedundancyStep* step) {
  const auto pose = AnchorPose(smap->map(), kf);
  if (!pose) {
    ++step->refused;
    return;
  }
  const KeyframeId id = kf.id();
  const auto info = smap->Info(id);
  const MapId segment = info ? info->segment : MapId();
  smap->AddAnchor(id, {base.id(), base.cam_from_world() * *pose, kf.stamp_ns(), segment});
  smap->map().EraseKeyframe(id);
  smap->EraseInfo(id);
  step->removed.push_back(id);
}

RedundancyStage::RedundancyStage(const RedundancyOptions& options, MapStack* stack)
    : min_map_keyframes_(options.min_map_keyframes), stack_(stack), remover_(options) {}

std::vector<KeyframeId> RedundancyStage::Step(const std::function<void(KeyframeId)>& on_removed) {
  auto maps = stack_->Maps();
  maps.erase(std::remove_if(maps.begin(), maps.end(),
                            [&](const auto& m) { return static_cast<int>(m->map().num_keyframes()) < min_map_keyframes_; }),
             maps.end());
  if (maps.empty()) return {};
  return OnMap(maps[next_++ % maps.size()], on_removed,
               [this](ServerMap* m, const std::vector<KeyframeId>& protect) { return remover_.Step(m, protect); });
}

std::vector<KeyframeId> RedundancyStage::SweepRevisits(MapId map, const std::function<void(KeyframeId)>& on_removed) {
  return OnMap(stack_->GetMap(map), on_removed, [this](ServerMap* m, const std::vector<KeyframeId>& protect) {
    return remover_.SweepRevisits(m, protect);
  });
}

std::vector<KeyframeId> RedundancyStage::OnMap(const std::shared_ptr<ServerMap>& smap,
                                               const std::function<void(KeyframeId)>& on_removed,
                                               const MapRun& run) {
  if (!smap) return {};
  std::shared_lock<WriterPreferringMutex> lock(smap->structure_mutex());
  if (smap->retired()) return {};
  std::vector<KeyframeId> protect;
  for (const AgentHandler& h : stack_->HandlersOfMap(smap->id())) protect.push_back(h.last_keyframe);
  const RedundancyStep step = run(smap.get(), protect);
  for (const KeyframeId id : step.removed) on_removed(id);
  return step.removed;
}

}  // namespace ccm
