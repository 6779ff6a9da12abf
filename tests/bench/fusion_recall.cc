#include "tests/bench/fusion_recall.h"

#include <algorithm>
#include <cstdio>

namespace ccm::bench {
namespace {

// Co-visibility shares: a true view shares this much with the query, a picked candidate
// counts as showing the place from this much on (the window view adds its neighbours).
constexpr double kTrueViewShare = 0.25;
constexpr double kPickedViewShare = 0.1;

class GroundTruthViews {
 public:
  GroundTruthViews(const sim::Simulation& sim, const sim::OverlapTruth& truth,
                   const std::map<KeyframeId, int64_t>& stamps, const std::vector<AgentId>& ids)
      : sim_(sim), truth_(truth), stamps_(stamps), ids_(ids) {}

  int AgentIndex(KeyframeId kf) const {
    const auto it = std::find(ids_.begin(), ids_.end(), kf.agent());
    return it == ids_.end() ? -1 : static_cast<int>(it - ids_.begin());
  }
  /// min(share_a, share_b) of two keyframes' true views (0 if not co-visible, -1 unknown).
  double Share(KeyframeId x, KeyframeId y) {
    const sim::SampledView* vx = View(x);
    const sim::SampledView* vy = View(y);
    if (!vx || !vy) return -1.0;
    const sim::ViewOverlap o = truth_.Compare(*vx, *vy);
    return o.covisible ? std::min(o.share_a, o.share_b) : 0.0;
  }

 private:
  const sim::SampledView* View(KeyframeId kf) {
    if (auto it = views_.find(kf); it != views_.end()) return &it->second;
    const auto st = stamps_.find(kf);
    const int a = AgentIndex(kf);
    if (st == stamps_.end() || a < 0) return nullptr;
    const double t = static_cast<double>(st->second - sim_.scenario().start_stamp_ns) * 1e-9;
    return &(views_[kf] = truth_.Sample(sim_, sim_.trajectory(a).WorldFromCam(t), t));
  }

  const sim::Simulation& sim_;
  const sim::OverlapTruth& truth_;
  const std::map<KeyframeId, int64_t>& stamps_;
  const std::vector<AgentId>& ids_;
  std::map<KeyframeId, sim::SampledView> views_;
};

void DiagnoseQuery(const FusionQueryTrace& t, int other, double min_common_ratio, GroundTruthViews* gt,
                   MissedPairDiagnosis* d) {
  ++d->queries;
  const QueryResult* best = nullptr;
  double best_share = 0.0;
  int max_common = 0;
  for (const QueryResult& r : t.scored) {
    max_common = std::max(max_common, r.common_words);
    if (gt->AgentIndex(r.keyframe) != other) continue;
    const double share = gt->Share(t.query, r.keyframe);
    if (share > best_share) best_share = share, best = &r;
  }
  if (!best || best_share < kTrueViewShare) return;
  ++d->with_true_view;
  for (const KeyframeId c : t.candidates) {
    if (gt->AgentIndex(c) != other || gt->Share(t.query, c) < kPickedViewShare) continue;
    ++d->retrieved;
    const auto v = std::find_if(t.verifications.begin(), t.verifications.end(),
                                [&](const FusionQueryTrace::Verification& v) { return v.query == t.query && v.candidate == c; });
    if (v == t.verifications.end()) {
      ++d->stopped_at["not verified"];  // its map changed meanwhile, or an earlier candidate was accepted
    } else {
      ++d->stopped_at[VerificationStageName(v->stage)];
      d->bow_matches.push_back(v->bow_matches);
    }
    return;
  }
  if (best->score < t.min_score) {
    ++d->below_score;
  } else if (best->common_words < min_common_ratio * max_common) {
    ++d->below_common_words;
  } else {
    ++d->cut_by_groups;
  }
}

}  // namespace

std::vector<MissedPairDiagnosis> DiagnoseMissedPairs(const sim::Simulation& sim, const sim::OverlapTruth& truth,
                                                     const SceneScore& score,
                                                     const std::vector<FusionQueryTrace>& traces,
                                                     const std::map<KeyframeId, int64_t>& stamps,
                                                     const std::vector<AgentId>& agent_ids, double min_common_ratio) {
  GroundTruthViews gt(sim, truth, stamps, agent_ids);
  std::vector<MissedPairDiagnosis> out;
  for (const PairScore& p : score.pairs) {
    // A pair that never fused was in two maps all along: every query of one could have
    // found the other's keyframes.
    if (!p.truth.qualifies || p.fused) continue;
    for (const int querying : {p.truth.a, p.truth.b}) {
      MissedPairDiagnosis d;
      d.a = p.truth.a;
      d.b = p.truth.b;
      d.querying = querying;
      const int other = querying == p.truth.a ? p.truth.b : p.truth.a;
      for (const FusionQueryTrace& t : traces) {
        if (gt.AgentIndex(t.query) == querying) DiagnoseQuery(t, other, min_common_ratio, &gt, &d);
      }
      std::sort(d.bow_matches.begin(), d.bow_matches.end());
      out.push_back(std::move(d));
    }
  }
  return out;
}

std::string FormatDiagnosis(const MissedPairDiagnosis& d) {
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "  recall %d-%d, queries by %d: %d, with a true view %d, retrieved %d; missed by score bar %d, "
                "common words %d, groups %d",
                d.a, d.b, d.querying, d.queries, d.with_true_view, d.retrieved, d.below_score, d.below_common_words,
                d.cut_by_groups);
  std::string s = buf;
  if (!d.stopped_at.empty()) {
    s += "; verification stopped at";
    for (const auto& [stage, n] : d.stopped_at) s += " " + stage + " " + std::to_string(n);
  }
  if (!d.bow_matches.empty()) {
    std::snprintf(buf, sizeof(buf), " (BoW matches median %d, max %d)", d.bow_matches[d.bow_matches.size() / 2],
                  d.bow_matches.back());
    s += buf;
  }
  return s + "\n";
}

}  // namespace ccm::bench
