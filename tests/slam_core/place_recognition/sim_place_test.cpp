// Place recognition on simulator scenes with ground truth: top-3 recall of revisits (hall3),
// no false positives after geometric verification (disjoint2, repeated), and recognition
// across cameras (pinhole database, fisheye / half-resolution queries).
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <memory>

#include "slam_core/place_recognition/keyframe_database.h"
#include "tests/slam_core/place_recognition/sim_keyframes.h"

namespace ccm::test {
namespace {

constexpr double kRevisitDistM = 0.5;
constexpr double kRevisitAngleDeg = 30.0;
constexpr double kSameAgentGapS = 10.0;   // a revisit by the same agent is this much later/earlier
// A verified Sim(3) is correct if it matches the ground truth this well (1% depth noise).
constexpr double kMaxTransErrM = 0.3;
constexpr double kMaxRotErrDeg = 5.0;

std::shared_ptr<const sim::Simulation> MakeSim(const std::string& name,
                                               const CameraIntrinsics* camera = nullptr,
                                               std::shared_ptr<const sim::World> world = nullptr) {
  std::string error;
  auto scenario = sim::LoadScenario(name, &error);
  EXPECT_TRUE(scenario) << error;
  if (camera) scenario->camera = *camera;
  std::shared_ptr<const sim::Simulation> s = sim::Simulation::Create(*scenario, &error, world);
  EXPECT_TRUE(s) << error;
  return s;
}

MapId MapOf(int agent) { return MapId::Make(static_cast<AgentId>(agent + 1), 1); }
KeyframeId IdOf(const SimKeyframe& kf) {
  return KeyframeId::Make(static_cast<AgentId>(kf.agent + 1), static_cast<std::uint64_t>(kf.index + 1));
}

struct Scene {
  std::vector<SimKeyframe> kfs;
  std::unique_ptr<KeyframeDatabase> db;
  std::map<KeyframeId, int> by_id;
};

Scene BuildScene(const sim::Simulation& s, std::int64_t stride, const std::vector<double>& scales) {
  Scene scene;
  const Vocabulary& vocab = DefaultVocabulary();
  scene.db = std::make_unique<KeyframeDatabase>(vocab.num_words());
  for (int a = 0; a < s.num_agents(); ++a) {
    SimKeyframeOptions o;
    o.stride = stride;
    o.map_scale = scales[a % scales.size()];
    o.seed = 7;
    for (auto& kf : MakeSimKeyframes(s, a, vocab, o)) scene.kfs.push_back(std::move(kf));
  }
  for (int i = 0; i < static_cast<int>(scene.kfs.size()); ++i) {
    scene.db->Add(IdOf(scene.kfs[i]), MapOf(scene.kfs[i].agent), scene.kfs[i].bow);
    scene.by_id[IdOf(scene.kfs[i])] = i;
  }
  return scene;
}

// Keyframes a query must not return: its own agent's within kSameAgentGapS.
QueryFilter TemporalExclusion(const Scene& scene, const SimKeyframe& q) {
  QueryFilter f;
  for (const auto& kf : scene.kfs) {
    if (kf.agent == q.agent && std::abs(kf.time_s - q.time_s) < kSameAgentGapS) {
      f.exclude_keyframes.push_back(IdOf(kf));
    }
  }
  return f;
}

struct VerifyStats {
  int accepted = 0, correct = 0, wrong = 0;
};

// Verifies `candidate` for `query`; counts the outcome against the ground truth.
// A match is right if the estimated Sim(3) agrees with the ground truth: two views of the same
// structure from far apart are a correct overlap too.
void VerifyAndCount(const SimKeyframe& candidate, const SimKeyframe& query, VerifyStats* stats) {
  const VerificationResult r = VerifyPlace(candidate.view, query.view);
  if (!r.accepted) return;
  ++stats->accepted;
  double dt, dr;
  Sim3Error(r.query_from_candidate, TrueQueryFromCandidate(candidate, query), query.map_scale, &dt, &dr);
  if (dt < kMaxTransErrM && dr < kMaxRotErrDeg) {
    ++stats->correct;
  } else {
    ++stats->wrong;
    std::printf("false positive: agent %d frame %lld -> agent %d frame %lld (%.2f m, %.1f deg, "
                "%d matches, support %.2f)\n", query.agent, static_cast<long long>(query.index), candidate.agent,
                static_cast<long long>(candidate.index), dt, dr, r.total_matches,
                r.spatial_support);
  }
}

TEST(SimPlaceRecognitionTest, Hall3RevisitRecallTop3) {
  auto s = MakeSim("hall3");
  ASSERT_TRUE(s);
  Scene scene = BuildScene(*s, 16, {1.0, 0.6, 1.7});
  int revisits = 0, hits = 0, strict_hits = 0, grouped_hits = 0;
  VerifyStats verify;
  // Covisibility stand-in: the same agent's keyframes up to two keyframes away.
  auto covisibility = [&scene](KeyframeId kf, int n) {
    std::vector<KeyframeId> out;
    const SimKeyframe& k = scene.kfs[scene.by_id.at(kf)];
    for (std::int64_t d : {-16, 16, -32, 32}) {
      const KeyframeId id = KeyframeId::Make(kf.agent(), static_cast<std::uint64_t>(k.index + d + 1));
      if (scene.by_id.count(id) && static_cast<int>(out.size()) < n) out.push_back(id);
    }
    return out;
  };
  CandidateOptions grouping;
  grouping.max_results = 3;
  for (const auto& q : scene.kfs) {
    const QueryFilter filter = TemporalExclusion(scene, q);
    bool has_revisit = false;
    for (const auto& c : scene.kfs) {
      if (c.agent == q.agent && std::abs(c.time_s - q.time_s) < kSameAgentGapS) continue;
      has_revisit |= SamePlace(q.world_from_cam, c.world_from_cam, kRevisitDistM, kRevisitAngleDeg);
    }
    if (!has_revisit) continue;
    ++revisits;
    bool hit = false, strict_hit = false;
    for (const auto& r : scene.db->Query(q.bow, filter, 3)) {
      const SimKeyframe& c = scene.kfs[scene.by_id.at(r.keyframe)];
      hit |= SamePlace(q.world_from_cam, c.world_from_cam, 2 * kRevisitDistM, kRevisitAngleDeg);
      strict_hit |= SamePlace(q.world_from_cam, c.world_from_cam, kRevisitDistM, kRevisitAngleDeg);
      VerifyAndCount(c, q, &verify);
    }
    hits += hit ? 1 : 0;
    strict_hits += strict_hit ? 1 : 0;
    bool grouped_hit = false;
    for (const auto& g : scene.db->DetectCandidates(q.bow, filter, grouping, covisibility)) {
      const SimKeyframe& c = scene.kfs[scene.by_id.at(g.best.keyframe)];
      grouped_hit |= SamePlace(q.world_from_cam, c.world_from_cam, 2 * kRevisitDistM, kRevisitAngleDeg);
    }
    grouped_hits += grouped_hit ? 1 : 0;
  }
  const double recall = revisits > 0 ? static_cast<double>(hits) / revisits : 0.0;
  std::printf("hall3: %zu keyframes, %d revisit queries, top-3 recall %.3f (candidate within "
              "0.5 m: %.3f); verification: %d accepted, %d correct, %d wrong\n", scene.kfs.size(),
              revisits, recall, static_cast<double>(strict_hits) / std::max(revisits, 1),
              verify.accepted, verify.correct, verify.wrong);
  EXPECT_GE(revisits, 30);
  std::printf("hall3: covisibility-grouped candidates (best of top-3 groups) recall %.3f\n",
              static_cast<double>(grouped_hits) / std::max(revisits, 1));
  EXPECT_GE(recall, 0.9);
  EXPECT_GE(grouped_hits, 0.9 * revisits);
  EXPECT_EQ(verify.wrong, 0);
  EXPECT_GT(verify.correct, revisits / 2);
}

// Queries every keyframe against the other agents' maps and its own (temporal exclusion);
// verified top-3 candidates must all be geometrically right.
VerifyStats RunFalsePositiveScenario(const std::string& name, std::int64_t stride) {
  auto s = MakeSim(name);
  Scene scene = BuildScene(*s, stride, {1.0, 1.4});
  VerifyStats verify;
  for (const auto& q : scene.kfs) {
    for (const auto& r : scene.db->Query(q.bow, TemporalExclusion(scene, q), 3)) {
      const SimKeyframe& c = scene.kfs[scene.by_id.at(r.keyframe)];
      VerifyAndCount(c, q, &verify);
    }
  }
  std::printf("%s: %zu keyframes, verification: %d accepted, %d correct, %d wrong\n", name.c_str(),
              scene.kfs.size(), verify.accepted, verify.correct, verify.wrong);
  return verify;
}

TEST(SimPlaceRecognitionTest, DisjointNoFalsePositives) {
  const VerifyStats v = RunFalsePositiveScenario("disjoint2", 24);
  EXPECT_EQ(v.wrong, 0);
}

TEST(SimPlaceRecognitionTest, RepeatedStructuresNoFalsePositives) {
  const VerifyStats v = RunFalsePositiveScenario("repeated", 24);
  EXPECT_EQ(v.wrong, 0);
  EXPECT_GT(v.correct, 0);  // real revisits are still found
}

// Every keyframe pair of `repeated` whose poses differ by one or more crate spacings (5 m
// along x) but otherwise match: the views show identical objects in different places.
TEST(SimPlaceRecognitionTest, RepeatedAliasedPairsRejected) {
  auto s = MakeSim("repeated");
  Scene scene = BuildScene(*s, 12, {1.0, 1.4});
  int pairs = 0;
  VerifyStats verify;
  for (const auto& q : scene.kfs) {
    for (const auto& c : scene.kfs) {
      bool aliased = false;
      for (double shift : {-15.0, -10.0, -5.0, 5.0, 10.0, 15.0}) {
        const SE3 shifted(c.world_from_cam.rotation(), c.world_from_cam.translation() + Eigen::Vector3d(shift, 0, 0));
        aliased |= SamePlace(q.world_from_cam, shifted, 0.7, 30.0);
      }
      if (!aliased || SamePlace(q.world_from_cam, c.world_from_cam, 3.0, 90.0)) continue;
      ++pairs;
      VerifyAndCount(c, q, &verify);
    }
  }
  std::printf("repeated aliased pairs: %d, accepted %d, wrong %d\n", pairs, verify.accepted, verify.wrong);
  EXPECT_GE(pairs, 20);
  EXPECT_EQ(verify.wrong, 0);
}

// Database from the pinhole agent; queries from the same flight seen by another camera,
// taken between the database keyframes.
void RunCrossCamera(const CameraIntrinsics& camera, const char* label) {
  auto pinhole = MakeSim("hall3");
  auto other = MakeSim("hall3", &camera, pinhole->world());
  const Vocabulary& vocab = DefaultVocabulary();
  KeyframeDatabase db(vocab.num_words());
  SimKeyframeOptions o;
  o.stride = 16;
  std::vector<SimKeyframe> kfs = MakeSimKeyframes(*pinhole, 0, vocab, o);
  for (const auto& kf : kfs) db.Add(IdOf(kf), MapOf(0), kf.bow);
  o.stride = 48;
  o.offset = 8;
  o.map_scale = 0.5;
  o.seed = 3;
  const std::vector<SimKeyframe> queries = MakeSimKeyframes(*other, 0, vocab, o);
  int hits = 0, verified = 0;
  VerifyStats verify;
  for (const auto& q : queries) {
    const auto results = db.Query(q.bow, {}, 3);
    bool hit = false;
    for (const auto& r : results) {
      const SimKeyframe& c = kfs[static_cast<std::size_t>(r.keyframe.counter() - 1) / 16];
      hit |= SamePlace(q.world_from_cam, c.world_from_cam, 2 * kRevisitDistM, kRevisitAngleDeg);
    }
    // The query counts as verified if one of its top-3 candidates verifies (as loop closing
    // would stop at the first).
    for (const auto& r : results) {
      const SimKeyframe& c = kfs[static_cast<std::size_t>(r.keyframe.counter() - 1) / 16];
      const int before = verify.correct;
      VerifyAndCount(c, q, &verify);
      if (verify.correct > before) {
        ++verified;
        break;
      }
    }
    hits += hit ? 1 : 0;
  }
  std::printf("%s: %zu queries, top-3 recall %.3f, verified %d, wrong %d\n", label, queries.size(),
              static_cast<double>(hits) / queries.size(), verified, verify.wrong);
  EXPECT_GE(hits, 0.9 * queries.size());
  EXPECT_EQ(verify.wrong, 0);
  EXPECT_GE(verified, 0.5 * queries.size());
}

TEST(GeometricVerificationTest, RejectsInvalidInputAndUnrelatedViews) {
  VerificationView empty;
  VerificationResult r = VerifyPlace(empty, empty);
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(r.reason.find("invalid input"), std::string::npos) << r.reason;
  EXPECT_EQ(r.stage, VerificationStage::kInput);
  // Two keyframes of disjoint2's two rooms: nothing in common.
  auto s = MakeSim("disjoint2");
  SimKeyframeOptions o;
  o.stride = 600;
  o.max_keyframes = 1;
  const auto a = MakeSimKeyframes(*s, 0, DefaultVocabulary(), o);
  const auto b = MakeSimKeyframes(*s, 1, DefaultVocabulary(), o);
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  r = VerifyPlace(a[0].view, b[0].view);
  EXPECT_FALSE(r.accepted);
  EXPECT_FALSE(r.reason.empty());
  // Different rooms share too few words to even try a Sim(3): stopped at the BoW matches.
  EXPECT_EQ(r.stage, VerificationStage::kBowMatches) << r.reason;
  EXPECT_STREQ(VerificationStageName(r.stage), "bow_matches");
  // The same keyframe against itself: accepted with the identity.
  r = VerifyPlace(a[0].view, a[0].view);
  EXPECT_TRUE(r.accepted) << r.reason;
  EXPECT_EQ(r.stage, VerificationStage::kAccepted);
  EXPECT_NEAR(r.query_from_candidate.scale(), 1.0, 1e-3);
  EXPECT_LT(r.query_from_candidate.translation().norm(), 1e-3);
  EXPECT_GE(r.total_matches, 100);
}

TEST(GeometricVerificationTest, ReprojectionRefinementRecoversPerturbedSim3) {
  auto s = MakeSim("hall3");
  SimKeyframeOptions o;
  o.stride = 10;
  o.offset = 200;
  o.max_keyframes = 2;
  const auto a = MakeSimKeyframes(*s, 0, DefaultVocabulary(), o);
  o.map_scale = 2.0;
  o.seed = 9;
  const auto b = MakeSimKeyframes(*s, 0, DefaultVocabulary(), o);
  const SimKeyframe& c = a[0];
  const SimKeyframe& q = b[1];  // 10 frames later, another map scale
  const VerificationResult r = VerifyPlace(c.view, q.view);
  ASSERT_TRUE(r.accepted) << r.reason;
  const Sim3 truth = TrueQueryFromCandidate(c, q);
  Eigen::Matrix<double, 7, 1> delta;
  delta << 0.05, -0.04, 0.03, 0.02, -0.03, 0.01, 0.04;
  const Sim3 start = Sim3::Exp(delta) * truth;
  double t0, r0, t1, r1;
  Sim3Error(start, truth, q.map_scale, &t0, &r0);
  const Sim3RefineResult refined = RefineSim3(c.view, q.view, r.matches, start);
  ASSERT_TRUE(refined.ok);
  Sim3Error(refined.query_from_candidate, truth, q.map_scale, &t1, &r1);
  std::printf("refinement: %.3f m / %.2f deg -> %.3f m / %.2f deg, %d inliers of %zu\n", t0, r0, t1, r1,
              refined.num_inliers, r.matches.size());
  EXPECT_LT(t1, 0.02);
  EXPECT_LT(r1, 0.5);
  EXPECT_NEAR(refined.query_from_candidate.scale(), truth.scale(), 0.02 * truth.scale());
  EXPECT_GE(refined.num_inliers, 50);
  // The same through VerifyPlace with the optimisation on.
  VerificationOptions with_opt;
  with_opt.optimize = true;
  const VerificationResult ro = VerifyPlace(c.view, q.view, with_opt);
  ASSERT_TRUE(ro.accepted) << ro.reason;
  Sim3Error(ro.query_from_candidate, truth, q.map_scale, &t1, &r1);
  EXPECT_LT(t1, 0.02);
}

TEST(SimPlaceRecognitionTest, CrossCameraFisheye) {
  RunCrossCamera(sim::FisheyeCamera(), "fisheye");
}

TEST(SimPlaceRecognitionTest, CrossCameraHalfResolution) {
  CameraIntrinsics half = sim::EurocCamera();
  half.width_px /= 2;
  half.height_px /= 2;
  half.fx /= 2;
  half.fy /= 2;
  half.cx /= 2;
  half.cy /= 2;
  RunCrossCamera(half, "half-resolution");
}

}  // namespace
}  // namespace ccm::test
