#include "tests/slam_core/place_recognition/retrieval_eval.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "slam_core/place_recognition/keyframe_database.h"

namespace ccm::test {
namespace {

KeyframeId IdOf(int i) { return KeyframeId::Make(1, static_cast<std::uint64_t>(i + 1)); }

bool Excluded(const SimKeyframe& q, const SimKeyframe& c, double min_gap_s) {
  return c.scene == q.scene && c.agent == q.agent && std::abs(c.time_s - q.time_s) < min_gap_s;
}

bool Near(const SimKeyframe& q, const SimKeyframe& c, double dist_m, double angle_deg) {
  return c.scene == q.scene && SamePlace(q.world_from_cam, c.world_from_cam, dist_m, angle_deg);
}

// Verifies every candidate; counts right / wrong Sim(3) (0.3 m, 5 deg, as sim_place_test).
bool VerifyCandidates(const SimKeyframe& q, const std::vector<const SimKeyframe*>& candidates,
                      RetrievalStats* stats) {
  bool any_correct = false;
  for (const SimKeyframe* c : candidates) {
    const VerificationResult r = VerifyPlace(c->view, q.view);
    if (!r.accepted) continue;
    double dt = 0, dr = 0;
    Sim3Error(r.query_from_candidate, TrueQueryFromCandidate(*c, q), q.map_scale, &dt, &dr);
    const bool correct = dt < 0.3 && dr < 5.0;
    (correct ? stats->verified_correct : stats->verified_wrong)++;
    any_correct |= correct;
  }
  return any_correct;
}

}  // namespace

void RetrievalStats::Add(const RetrievalStats& o) {
  keyframes += o.keyframes;
  queries += o.queries;
  hits_top1 += o.hits_top1;
  hits_topk += o.hits_topk;
  verified_correct += o.verified_correct;
  verified_wrong += o.verified_wrong;
  queries_verified += o.queries_verified;
  query_ms.insert(query_ms.end(), o.query_ms.begin(), o.query_ms.end());
}

RetrievalStats ScoreRetrieval(const std::vector<SimKeyframe>& kfs, std::size_t num_words,
                              const RetrievalOptions& options) {
  // Agents share one map id space here: the database only needs distinct keyframe ids.
  KeyframeDatabase db(num_words);
  for (int i = 0; i < static_cast<int>(kfs.size()); ++i) {
    db.Add(IdOf(i), MapId::Make(static_cast<AgentId>(kfs[i].agent + 1), 1), kfs[i].bow);
  }
  RetrievalStats stats;
  stats.keyframes = static_cast<int>(kfs.size());
  for (const auto& q : kfs) {
    if (options.query_scene && q.scene != *options.query_scene) continue;
    QueryFilter filter;
    bool has_revisit = false;
    for (int i = 0; i < static_cast<int>(kfs.size()); ++i) {
      if (Excluded(q, kfs[i], options.min_gap_s)) {
        filter.exclude_keyframes.push_back(IdOf(i));
      } else {
        has_revisit |= Near(q, kfs[i], options.revisit_dist_m, options.max_angle_deg);
      }
    }
    const auto t0 = std::chrono::steady_clock::now();
    const auto results = db.Query(q.bow, filter, options.top_k);
    stats.query_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (!has_revisit) continue;
    ++stats.queries;
    std::vector<const SimKeyframe*> candidates;
    bool hit = false;
    for (std::size_t r = 0; r < results.size(); ++r) {
      const SimKeyframe& c = kfs[results[r].keyframe.counter() - 1];
      candidates.push_back(&c);
      const bool near = Near(q, c, options.hit_dist_m, options.max_angle_deg);
      if (near && r == 0) ++stats.hits_top1;
      hit |= near;
    }
    stats.hits_topk += hit ? 1 : 0;
    if (options.verify && VerifyCandidates(q, candidates, &stats)) ++stats.queries_verified;
  }
  return stats;
}

void TransformKeyframes(const Vocabulary& vocab, int levels_up, std::vector<SimKeyframe>* kfs) {
  if (levels_up < 0) levels_up = std::max(0, vocab.levels() - 2);
  for (auto& kf : *kfs) vocab.Transform(kf.view.features.descriptors, &kf.bow, &kf.view.feature_vector, levels_up);
}

std::string MakeDatasetKeyframes(FrameSource* source, const Vocabulary& vocab, int num_features, int scene,
                                 std::vector<SimKeyframe>* kfs) {
  OrbExtractorOptions orb;
  orb.num_features = num_features;
  OrbExtractor extractor(orb);
  std::shared_ptr<const CameraModel> camera = MakeCamera(source->intrinsics());
  std::int64_t index = 0;
  std::int64_t first_stamp = -1;
  std::vector<SimKeyframe> made;
  while (auto frame = source->Next()) {
    const std::int64_t i = index++;
    if (!frame->world_from_cam_gt) continue;
    if (first_stamp < 0) first_stamp = frame->stamp_ns;
    SimKeyframe kf;
    kf.scene = scene;
    kf.index = i;
    kf.time_s = 1e-9 * static_cast<double>(frame->stamp_ns - first_stamp);
    kf.world_from_cam = *frame->world_from_cam_gt;
    kf.view.camera = camera;
    kf.view.pyramid = extractor.pyramid();
    kf.view.features = extractor.Extract(frame->image);
    kf.view.points_cam.assign(kf.view.features.size(),
                              Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    made.push_back(std::move(kf));
  }
  TransformKeyframes(vocab, -1, &made);
  for (auto& kf : made) kfs->push_back(std::move(kf));
  return source->error();
}

std::string MakeScenarioKeyframes(const std::string& scenario, const Vocabulary& vocab, double spacing_s,
                                  int scene, std::vector<SimKeyframe>* kfs) {
  std::string error;
  auto s = sim::LoadScenario(scenario, &error);
  if (!s) return scenario + ": " + error;
  std::shared_ptr<const sim::Simulation> simulation = sim::Simulation::Create(*s, &error);
  if (!simulation) return scenario + ": " + error;
  // Per-agent map scales as a monocular team would have (verification works in Sim(3)).
  const double scales[] = {1.0, 0.6, 1.7};
  for (int a = 0; a < simulation->num_agents(); ++a) {
    SimKeyframeOptions o;
    o.stride = std::max<std::int64_t>(1, std::llround(spacing_s * s->agents[a].rate_hz));
    o.map_scale = scales[a % 3];
    for (auto& kf : MakeSimKeyframes(*simulation, a, vocab, o)) {
      kf.scene = scene;
      kfs->push_back(std::move(kf));
    }
  }
  return {};
}

}  // namespace ccm::test
