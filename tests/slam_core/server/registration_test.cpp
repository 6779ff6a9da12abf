// Registration and the agent -> server value types on real VO output (hall3 excerpts):
// relative poses reproduce the VO map, the server reproduces the agent's trajectory from
// them, points that arrive before their keyframe wait, and lambda follows a scale change
// (malformed input and the intake's limits: intake_limits_test.cpp).
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <optional>
#include <set>

#include "slam_core/eval/alignment.h"
#include "slam_core/eval/metrics.h"
#include "tests/slam_core/server/server_test_util.h"

namespace ccm {
namespace {

using testing::LoadSim;
using testing::RunVoStream;
using testing::SimVocabulary;

using testing::Hall3Stream;

// The whole stream into the back-end, one batch at a time, as the comm module would.
void SubmitAll(const testing::VoStream& s, ServerBackend* backend) {
  for (const AgentBatch& b : s.batches) {
    backend->Submit(b);
    backend->ProcessAllQueued();
  }
}

TEST(ChangePacker, RelativePosesReproduceTheVoMap) {
  const auto sim = LoadSim("hall3");
  ASSERT_NE(sim, nullptr);
  const testing::VoStream s = RunVoStream(sim, 0, 0, 120, /*period_frames=*/1000);
  ASSERT_EQ(s.batches.size(), 1u);
  const Map& map = *s.final_map;
  const AgentBatch& b = s.batches.front();
  ASSERT_GE(b.keyframes.size(), 5u);
  EXPECT_TRUE(b.keyframe_updates.empty()) << "nothing was sent before: all keyframes go out in full";
  int checked = 0;
  for (const KeyframeData& k : b.keyframes) {
    EXPECT_EQ(ValidateKeyframeData(k, b.agent), "");
    const auto kf = map.keyframe(k.id);
    ASSERT_NE(kf, nullptr);
    if (const auto pred = k.predecessor.valid() ? map.keyframe(k.predecessor) : nullptr) {
      const SE3 rebuilt = pred->world_from_cam() * k.pred_from_cam;
      EXPECT_LT((rebuilt.translation() - kf->camera_center()).norm(), 1e-9);
      EXPECT_LT(pred->id(), k.id);
      ++checked;
    }
    for (const auto& [idx, mp] : k.point_links) EXPECT_EQ(kf->MapPointAt(idx), mp);
  }
  EXPECT_EQ(checked + 1, static_cast<int>(b.keyframes.size())) << "every keyframe but the first has a predecessor";
  for (const MapPointData& m : b.map_points) {
    EXPECT_EQ(ValidateMapPointData(m, b.agent), "");
    const auto ref = map.keyframe(m.reference_kf);
    ASSERT_NE(ref, nullptr);
    EXPECT_LT((ref->world_from_cam() * m.position_ref - map.map_point(m.id)->position()).norm(), 1e-9);
  }
}

TEST(Registration, ServerReproducesTheAgentsKeyframeTrajectory) {
  const testing::VoStream& s = Hall3Stream();
  ServerOptions o;
  ServerBackend backend(SimVocabulary(), o);
  for (const AgentBatch& b : s.batches) {
    ASSERT_EQ(backend.Submit(b), 0);
    backend.ProcessAllQueued();
  }
  const auto server = backend.Snapshot().AgentTrajectory(1);
  ASSERT_GE(server.size(), s.keyframes.size() * 9 / 10);
  // The segment's first keyframe defines the server map's frame, so server and VO poses are
  // directly comparable; they differ only by the server's refinement and mapping.
  std::vector<Eigen::Vector3d> est, gt;
  double worst = 0.0;
  for (const ServerKeyframePose& p : server) {
    for (const KeyframePose& v : s.keyframes) {
      if (v.id != p.id) continue;
      worst = std::max(worst, (v.world_from_cam.translation() - p.world_from_cam.translation()).norm());
      est.push_back(p.world_from_cam.translation());
      gt.push_back(testing::GroundTruthAt(s.ground_truth, p.stamp_ns)->translation());
    }
  }
  const double path = PathLengthM([&] {
    std::vector<SE3> poses;
    for (const auto& g : s.ground_truth) poses.push_back(g.world_from_cam);
    return poses;
  }());
  std::string error;
  const auto align = UmeyamaAlignment(est, gt, true, &error);
  ASSERT_TRUE(align) << error;
  std::vector<double> errors;
  for (size_t i = 0; i < est.size(); ++i) errors.push_back((*align * est[i] - gt[i]).norm());
  const double ate = ComputeStats(errors).rmse;
  const double vo_scale_path = path / align->scale();  // path in VO units
  EXPECT_LT(worst, 0.02 * vo_scale_path) << "server poses stay within 2% of the path of the VO's";
  EXPECT_LT(ate, 0.005 * path) << "ATE " << ate << " m over " << path << " m";
  const BackendStats st = backend.Status().stats;
  EXPECT_EQ(st.agents.at(1).rejected, 0);
  EXPECT_GT(st.agents.at(1).updates_applied, 0) << "the agent's local-BA updates reach the server";
}

// After an outage the keyframes come before their points, flagged by the reassembly: the
// back-end registers them (and acknowledges them) at once, but maps them and queries place
// recognition only once their points came; a query without 3-D points cannot verify a match.
TEST(Registration, KeyframesThatCameBeforeTheirPointsAreQueriedOnceThePointsCame) {
  const testing::VoStream& s = Hall3Stream();
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  const size_t half = s.batches.size() / 2;
  for (size_t i = 0; i < half; ++i) {
    ASSERT_EQ(backend.Submit(s.batches[i]), 0);
    backend.ProcessAllQueued();
  }
  const int64_t queries_before = backend.Status().stats.place.queries;
  std::vector<AgentBatch> late;
  int flagged = 0;
  for (size_t i = half; i < s.batches.size(); ++i) {
    AgentBatch b = s.batches[i];
    AgentBatch points;
    points.agent = b.agent;
    points.segment = b.segment;
    points.stamp_ns = b.stamp_ns;
    std::swap(points.map_points, b.map_points);
    for (KeyframeData& k : b.keyframes) {
      k.points_incomplete = !k.anchor_only;
      flagged += k.points_incomplete;
    }
    late.push_back(std::move(points));
    ASSERT_EQ(backend.Submit(b), 0);
    backend.ProcessAllQueued();
  }
  ASSERT_GT(flagged, 10);
  const BackendStats burst = backend.Status().stats;
  EXPECT_GT(burst.agents.at(1).keyframes_deferred, flagged / 2) << "keyframes linking points not here yet wait";
  const int64_t queried_early = burst.place.queries - queries_before;
  EXPECT_LT(queried_early, flagged - burst.agents.at(1).keyframes_deferred + 1)
      << "no deferred keyframe was queried before its points";
  for (const AgentBatch& b : late) {
    ASSERT_EQ(backend.Submit(b), 0);
    backend.ProcessAllQueued();
  }
  const BackendStats after = backend.Status().stats;
  // Mapped late, a keyframe next to a later one of the burst may become its anchor instead
  // (near-duplicate): either way it was handled once its points came.
  const int64_t queried = after.place.queries - burst.place.queries;
  const int64_t anchored = after.agents.at(1).keyframes_duplicate - burst.agents.at(1).keyframes_duplicate;
  std::printf("flagged %d, deferred %lld, queried before their points %lld, after: queried %lld, anchored %lld\n",
              flagged, static_cast<long long>(burst.agents.at(1).keyframes_deferred),
              static_cast<long long>(queried_early), static_cast<long long>(queried), static_cast<long long>(anchored));
  EXPECT_GE(queried, 3);
  EXPECT_GE(queried + anchored, burst.agents.at(1).keyframes_deferred * 9 / 10)
      << "once their points came, the deferred keyframes were mapped and queried";
  EXPECT_EQ(after.agents.at(1).rejected, 0);
}

TEST(Registration, AgentUpdatesStillApplyAfterTheRegistrationRefinement) {
  // The server refines each keyframe against the points it links when it registers it; the
  // agent's local BA keeps improving that keyframe and its points afterwards. With nothing
  // else on the server touching them (no local BA, no loop), the agent's updates must win:
  // the server's map ends where the agent's VO map ended.
  const testing::VoStream& s = Hall3Stream();
  ServerOptions o;
  o.mapping.local_ba = false;
  o.mapping.duplicate_distance_ratio = 0.0;
  ServerBackend backend(SimVocabulary(), o);
  SubmitAll(s, &backend);
  ASSERT_EQ(backend.Status().stats.loops, 0);
  std::vector<double> kf_diffs;
  for (const ServerKeyframePose& p : backend.Snapshot().AgentTrajectory(1)) {
    for (const KeyframePose& v : s.keyframes) {
      if (v.id == p.id) kf_diffs.push_back((v.world_from_cam.translation() - p.world_from_cam.translation()).norm());
    }
  }
  ASSERT_GE(kf_diffs.size(), s.keyframes.size() * 9 / 10);
  std::sort(kf_diffs.begin(), kf_diffs.end());
  double vo_path = 0.0;  // in VO units, as the differences
  for (size_t i = 1; i < s.keyframes.size(); ++i) {
    vo_path += (s.keyframes[i].world_from_cam.translation() - s.keyframes[i - 1].world_from_cam.translation()).norm();
  }
  const double median = kf_diffs[kf_diffs.size() / 2] / vo_path, worst = kf_diffs.back() / vo_path;
  std::printf("  %zu keyframes: server vs VO median %.3f %%, worst %.3f %% of the path\n", kf_diffs.size(),
              100 * median, 100 * worst);
  // The server's running scale estimate (kappa-filtered) keeps a small steady offset. When
  // the registration refinement froze keyframes, the worst was 2.4 % of the path off.
  EXPECT_LT(median, 0.002);
  EXPECT_LT(worst, 0.004);
}

TEST(Registration, NearDuplicatesSentAsAnchorsLandAtTheirVoPose) {
  // ccm_agent's packing: keyframes leave 1.5 s old, near-duplicates of keyframes the server
  // has in full leave as pose anchors only.
  ChangePackerOptions packing;
  packing.new_keyframe_delay_s = 1.5;
  packing.anchor_duplicates = NearDuplicateRule{};
  const testing::VoStream s = RunVoStream(LoadSim("hall3"), 0, 0, 200, 5, {}, 1, packing);
  std::set<KeyframeId> full, anchors;
  for (const AgentBatch& b : s.batches) {
    for (const KeyframeData& kf : b.keyframes) {
      EXPECT_EQ(ValidateKeyframeData(kf, b.agent), "");
      // Nothing hangs on an anchor: its pose on the server is never updated.
      EXPECT_FALSE(anchors.count(kf.predecessor) || anchors.count(kf.parent)) << "placed relative to an anchor";
      if (!kf.anchor_only) {
        full.insert(kf.id);
        continue;
      }
      EXPECT_TRUE(full.count(kf.parent)) << "an anchor hangs on a keyframe the server has in full";
      anchors.insert(kf.id);
    }
    for (const KeyframePoseUpdate& u : b.keyframe_updates) {
      EXPECT_FALSE(anchors.count(u.id) || anchors.count(u.predecessor) || anchors.count(u.parent));
    }
    // (A point sent earlier may name a keyframe that was still to be sent then.)
    for (const MapPointData& mp : b.map_points) {
      EXPECT_FALSE(anchors.count(mp.reference_kf)) << "a point is placed relative to a keyframe the server has";
      for (const auto& obs : mp.observations) EXPECT_FALSE(anchors.count(obs.first)) << "anchors have no keypoints";
    }
  }
  ASSERT_GE(anchors.size(), 3u) << full.size() << " keyframes in full, no near-duplicates found";
  EXPECT_GE(full.size(), anchors.size() / 2) << "most keyframes cannot be near-duplicates of others";
  std::printf("[ info     ] %zu keyframes sent in full, %zu as anchors\n", full.size(), anchors.size());
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  for (const AgentBatch& b : s.batches) {
    ASSERT_EQ(backend.Submit(b), 0);
    backend.ProcessAllQueued();
  }
  EXPECT_EQ(backend.Status().stats.agents.at(1).keyframes_anchor_only, static_cast<int64_t>(anchors.size()));
  // Every anchor is in the server's trajectory (not in its map), where the VO put it.
  const double vo_path = PathLengthM([&] {
    std::vector<SE3> poses;
    for (const auto& k : s.keyframes) poses.push_back(k.world_from_cam);
    return poses;
  }());
  size_t found = 0;
  for (const ServerKeyframePose& p : backend.Snapshot().AgentTrajectory(1)) {
    if (!anchors.count(p.id)) continue;
    ++found;
    const auto smap = backend.Snapshot().MapHolding(p.id);
    ASSERT_NE(smap, nullptr);
    EXPECT_EQ(smap->map().keyframe(p.id), nullptr);
    for (const KeyframePose& v : s.keyframes) {
      if (v.id != p.id) continue;
      EXPECT_LT((v.world_from_cam.translation() - p.world_from_cam.translation()).norm(), 0.02 * vo_path);
      EXPECT_LT(v.world_from_cam.rotation().angularDistance(p.world_from_cam.rotation()), 0.02);
    }
  }
  EXPECT_EQ(found, anchors.size());
}

TEST(Registration, ObservationsCarriedByKeyframeLinksReachTheServersPoints) {
  // Points travel with only the observations no keyframe link carries; the server attaches
  // the links of keyframes that arrived before their points.
  const testing::VoStream& s = Hall3Stream();
  size_t points = 0, observations_sent = 0;
  for (const AgentBatch& b : s.batches) {
    points += b.map_points.size();
    for (const MapPointData& mp : b.map_points) observations_sent += mp.observations.size();
  }
  ASSERT_GT(points, 500u);
  // A triangulated point has >= 2 observations when it is created; sent with all of them,
  // that would be >= 2 per point.
  EXPECT_LT(observations_sent, 2 * points) << "observations that keyframe links carry went with the points too";
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  SubmitAll(s, &backend);
  const auto smap = backend.Snapshot().MapHolding(s.batches.front().keyframes.front().id);
  ASSERT_NE(smap, nullptr);
  size_t on_server = 0, observed_twice = 0;
  for (const auto& mp : smap->map().map_points()) {
    ++on_server;
    observed_twice += mp->num_observations() >= 2;
  }
  EXPECT_GE(backend.Status().stats.agents.at(1).points_registered, static_cast<int64_t>(points * 9 / 10));
  EXPECT_GE(observed_twice, on_server * 8 / 10) << "links did not reach the points";
}

TEST(Registration, DelayedKeyframesLinkOnlyPointsThatLeftWithThemOrBefore) {
  // ccm_agent's packing: a keyframe leaves 1.5 s old, when younger keyframes have added
  // points it observes; those wait for their own reference keyframe. The server holds a
  // keyframe until its linked points arrive, so such links would hold it for nothing: the
  // observation goes with the point instead, and must still reach the server.
  ChangePackerOptions packing;
  packing.new_keyframe_delay_s = 1.5;
  const testing::VoStream s = RunVoStream(LoadSim("hall3"), 0, 0, 200, 5, {}, 1, packing);
  std::set<MapPointId> sent;
  size_t own_links = 0;
  for (const AgentBatch& b : s.batches) {
    for (const MapPointData& mp : b.map_points) sent.insert(mp.id);
    for (const KeyframeData& kf : b.keyframes) {
      for (const auto& [idx, mp] : kf.point_links) {
        if (mp.agent() != b.agent) continue;
        ++own_links;
        EXPECT_TRUE(sent.count(mp)) << "keyframe " << kf.id.counter() << " links point " << mp.counter()
                                    << " that has not left yet";
      }
    }
  }
  ASSERT_GT(own_links, 1000u);
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  SubmitAll(s, &backend);
  // Every observation of a sent point by a sent keyframe in the VO's final map should be on
  // the server (some differ: the server fuses duplicates and culls outliers; the VO goes on
  // after its last batch).
  const auto smap = backend.Snapshot().MapHolding(s.batches.front().keyframes.front().id);
  ASSERT_NE(smap, nullptr);
  size_t vo_obs = 0, on_server = 0;
  for (const auto& mp : s.final_map->map_points()) {
    if (!sent.count(mp->id())) continue;
    const auto server_mp = smap->map().map_point(smap->Resolve(mp->id()));
    for (const auto& [kf, idx] : mp->observations()) {
      if (!smap->map().keyframe(kf)) continue;  // not sent in full (yet)
      ++vo_obs;
      on_server += server_mp && smap->map().keyframe(kf)->MapPointAt(idx) == server_mp->id();
    }
  }
  ASSERT_GT(vo_obs, 1000u);
  EXPECT_GE(on_server, vo_obs * 85 / 100) << on_server << " of " << vo_obs << " observations reached the server";
}

TEST(Registration, PointsArrivingBeforeTheirKeyframeWaitAndLand) {
  const testing::VoStream& s = Hall3Stream();
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  size_t points = 0;
  for (const AgentBatch& b : s.batches) {
    // Points first (as DDS may deliver them), keyframes in a second message.
    AgentBatch only_points = b, only_keyframes = b;
    only_points.keyframes.clear();
    only_keyframes.map_points.clear();
    points += b.map_points.size();
    backend.Submit(only_points);
    backend.Submit(only_keyframes);
    backend.ProcessAllQueued();
  }
  const BackendStats st = backend.Status().stats;
  EXPECT_GE(st.agents.at(1).points_registered, static_cast<int64_t>(points * 95 / 100));
  size_t acked = 0;
  for (const MapPointId id : backend.TakeAcks(1).map_points) acked += id.valid();
  EXPECT_GE(acked, points * 95 / 100) << "waiting points are acknowledged once they land";
}

// Pose of `kf` in the server map holding it after the last batch (nullopt if not in a map).
std::optional<SE3> ServerPose(const ServerBackend& backend, KeyframeId kf) {
  for (const ServerKeyframePose& p : backend.Snapshot().AgentTrajectory(kf.agent())) {
    if (p.id == kf && p.in_map) return p.world_from_cam;
  }
  return std::nullopt;
}

// Registers the first 2/3 of the hall3 stream, then one keyframe that also links old map
// points as the server would hold them if the agent had drifted: 1.5x as many such links
// as its own, half of them where a drift of `shift_depth_ratio` (8 %) of the scene depth
// along the camera's x axis puts them, half for the same drift along y (no pose agrees with
// most links), or with `one_drift` all along x (one pose agrees with most links). Returns
// the keyframe's distance from where its predecessor places it, and how many of the
// drifted links the server kept.
struct RevisitOutcome {
  double offset = -1.0, shift = 0.0;
  int drifted_links = 0, drifted_kept = 0;
  int64_t kept_on_track = 0, refused = 0;
};
RevisitOutcome RegisterDriftedRevisit(double shift_depth_ratio = 0.08, bool one_drift = false,
                                      ServerOptions options = {}) {
  const testing::VoStream& s = Hall3Stream();
  // Without its new points the keyframe would be anchored as a near-duplicate (not in the map).
  options.mapping.duplicate_distance_ratio = 0.0;
  ServerBackend backend(SimVocabulary(), options);
  const size_t cut = s.batches.size() * 2 / 3;
  for (size_t i = 0; i < cut; ++i) {
    backend.Submit(s.batches[i]);
    backend.ProcessAllQueued();
  }
  AgentBatch b = s.batches[cut];
  b.keyframes.resize(1);
  b.map_points.clear();
  b.keyframe_updates.clear();
  b.map_point_updates.clear();
  KeyframeData& k = b.keyframes.front();
  RevisitOutcome out;
  const auto pred = ServerPose(backend, k.predecessor);
  const auto smap = backend.Snapshot().MapHolding(k.predecessor);
  if (!pred || !smap || k.anchor_only) return out;
  const SE3 placed = *pred * k.pred_from_cam;  // lambda is ~1: the map is the VO's frame
  const double depth = MedianSceneDepth(smap->map(), *smap->map().keyframe(k.predecessor));
  out.shift = shift_depth_ratio * depth;
  const std::array<SE3, 2> drifted = {
      SE3(placed.rotation(), placed.translation() + placed.rotation() * Eigen::Vector3d(out.shift, 0, 0)),
      SE3(placed.rotation(), placed.translation() + placed.rotation() * Eigen::Vector3d(0, out.shift, 0))};
  std::set<MapPointId> recent;
  for (const MapPointId id : smap->map().keyframe(k.predecessor)->map_points()) recent.insert(id);
  for (const auto& [idx, id] : k.point_links) recent.insert(id);
  FrameFeatures features = *k.features;
  const size_t wanted = 3 * k.point_links.size() / 2;
  for (const auto& mp : smap->map().map_points()) {
    if (out.drifted_links >= static_cast<int>(wanted)) break;
    Eigen::Vector2d uv;
    const Eigen::Vector3d p = drifted[one_drift ? 0 : out.drifted_links % 2].inverse() * mp->position();
    if (recent.count(mp->id()) || p.z() < 0.1 || !k.camera->Project(p, &uv)) continue;
    if (uv.x() < 1 || uv.y() < 1 || uv.x() > k.camera->width() - 2 || uv.y() > k.camera->height() - 2) continue;
    Keypoint kp;
    kp.u = static_cast<float>(uv.x());
    kp.v = static_cast<float>(uv.y());
    k.point_links.emplace_back(static_cast<int>(features.keypoints.size()), mp->id());
    features.keypoints.push_back(kp);
    features.descriptors.push_back(mp->descriptor());
    ++out.drifted_links;
  }
  const size_t first_added = k.features->size();
  k.features = std::make_shared<const FrameFeatures>(std::move(features));
  backend.Submit(b);
  backend.ProcessAllQueued();
  out.kept_on_track = backend.Status().stats.agents.at(1).keyframes_kept_on_track;
  out.refused = backend.Status().stats.agents.at(1).refinements_refused;
  const auto pose = ServerPose(backend, k.id);
  const auto kf = smap->map().keyframe(k.id);
  if (!pose || !kf) return out;
  out.offset = (pose->translation() - placed.translation()).norm();
  for (size_t i = first_added; i < kf->features().size(); ++i) out.drifted_kept += kf->MapPointAt(i).valid();
  return out;
}

TEST(Registration, AKeyframeWhoseLinksMostlyDisagreeKeepsToItsTrackAndDropsThem) {
  // An agent back where it was, tracking old points that the server holds elsewhere (drift
  // not yet closed as a loop): most of the keyframe's links agree on no pose. Left in the
  // map, they tear it at this keyframe in the next local BA (seen on a held-out scene: the
  // agent's part of the fused map went from 1 cm to 0.66 m ATE). The points its predecessor
  // sees as well place it; the links that disagree are dropped.
  const RevisitOutcome r = RegisterDriftedRevisit();
  std::printf("  %d drifted links (shift %.3f): keyframe %.4f from its placement, %d drifted links kept\n",
              r.drifted_links, r.shift, r.offset, r.drifted_kept);
  ASSERT_GE(r.drifted_links, 100);
  ASSERT_GE(r.offset, 0.0) << "the keyframe is not in the map";
  EXPECT_EQ(r.kept_on_track, 1);
  EXPECT_LT(r.offset, 0.15 * r.shift);
  EXPECT_LT(r.drifted_kept, r.drifted_links / 10);
}

TEST(Registration, MostLinksAgreeingOnAPoseFarFromTheTrackDoNotMoveTheKeyframe) {
  // As above, but all drifted links agree on one pose, 30 % of the scene depth off the
  // track: the refinement fits it (60 % of the links agree: most, not a clear majority), yet
  // the agent's VO does not drift that far from one keyframe to the next, and the links the
  // keyframe shares with its predecessor do not go there. Seen on an unseen scene after a
  // loop had moved the points an agent was coming back to: 20 of 38 links pulled its
  // keyframe 2 m back along a 1 m step, every later keyframe hung on it, and the agent's part
  // of the fused map went from 0.014 to 0.25 m ATE. The pull is refused and the
  // predecessor's points place it.
  const RevisitOutcome r = RegisterDriftedRevisit(0.3, /*one_drift=*/true);
  std::printf("  %d drifted links (shift %.3f): keyframe %.4f from its placement, %d drifted links kept\n",
              r.drifted_links, r.shift, r.offset, r.drifted_kept);
  ASSERT_GE(r.drifted_links, 100);
  ASSERT_GE(r.offset, 0.0) << "the keyframe is not in the map";
  EXPECT_EQ(r.kept_on_track, 1);
  EXPECT_EQ(r.refused, 1);
  EXPECT_LT(r.offset, 0.1 * r.shift);
  EXPECT_LT(r.drifted_kept, r.drifted_links / 10);
  // The same keyframe with the bound lifted goes where the drifted links put it: the test
  // sees the bound's doing, not a keyframe that could not have moved anyway.
  ServerOptions unbounded;
  unbounded.registration.refine_max_step_share = 1e6;
  unbounded.registration.refine_min_pull_depth_ratio = 1e6;
  const RevisitOutcome u = RegisterDriftedRevisit(0.3, true, unbounded);
  std::printf("  without the bound: keyframe %.4f from its placement, %d drifted links kept\n", u.offset,
              u.drifted_kept);
  EXPECT_GT(u.offset, 0.8 * u.shift);
  EXPECT_EQ(u.refused, 0);
}

TEST(Registration, ScaleFactorFollowsAScaleChangeOfTheVo) {
  // From the middle on, the agent's VO reports every translation 1.5x longer (as after a
  // scale jump): refinement against the server's points measures the true motion, and the
  // handler's lambda moves from 1 towards 1/1.5 (Forster et al.'s estimator).
  const testing::VoStream& s = Hall3Stream();
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  const double k = 1.5;
  for (size_t i = 0; i < s.batches.size(); ++i) {
    AgentBatch b = s.batches[i];
    if (i >= s.batches.size() / 3) {
      for (auto& kf : b.keyframes) {
        kf.pred_from_cam = SE3(kf.pred_from_cam.rotation(), kf.pred_from_cam.translation() * k);
        kf.parent_from_cam = SE3(kf.parent_from_cam.rotation(), kf.parent_from_cam.translation() * k);
      }
      for (auto& mp : b.map_points) mp.position_ref *= k;
      b.keyframe_updates.clear();
      b.map_point_updates.clear();
    }
    backend.Submit(b);
    backend.ProcessAllQueued();
  }
  const auto handlers = testing::HandlersOf(backend.Snapshot(), 1);
  ASSERT_EQ(handlers.size(), 1u);
  EXPECT_LT(handlers[0].scale, 0.9) << "lambda " << handlers[0].scale << " did not move towards " << 1.0 / k;
  EXPECT_GT(handlers[0].scale, 1.0 / k - 0.05);
}

}  // namespace
}  // namespace ccm
