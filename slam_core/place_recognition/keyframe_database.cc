#include "slam_core/place_recognition/keyframe_database.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <unordered_set>

namespace ccm {

namespace {

template <typename T>
bool ContainsValue(const std::vector<T>& v, T x) {
  return std::find(v.begin(), v.end(), x) != v.end();
}

bool ByScore(const QueryResult& a, const QueryResult& b) {
  if (a.score != b.score) return a.score > b.score;
  return a.keyframe < b.keyframe;
}

}  // namespace

std::string CandidateOptions::Validate() const {
  if (min_score < 0.0 || min_score > 1.0) return "min_score must be in [0, 1]";
  if (min_common_ratio < 0.0 || min_common_ratio > 1.0) return "min_common_ratio must be in [0, 1]";
  if (group_ratio < 0.0 || group_ratio > 1.0) return "group_ratio must be in [0, 1]";
  if (covisible_neighbours < 0) return "covisible_neighbours must be >= 0";
  if (max_results < 0) return "max_results must be >= 0";
  return {};
}

KeyframeDatabase::KeyframeDatabase(std::size_t num_words) : inverted_(num_words) {}

void KeyframeDatabase::Add(KeyframeId keyframe, MapId map, const BowVector& bow) {
  std::unique_lock lock(mutex_);
  EraseLocked(keyframe);
  std::uint32_t slot;
  if (!free_slots_.empty()) {
    slot = free_slots_.back();
    free_slots_.pop_back();
  } else {
    slot = static_cast<std::uint32_t>(slots_.size());
    slots_.emplace_back();
  }
  Slot& s = slots_[slot];
  s.keyframe = keyframe;
  s.map = map;
  s.agent = keyframe.agent();
  s.alive = true;
  s.bow = bow;
  for (const auto& [word, weight] : bow.entries) {
    if (word < inverted_.size()) inverted_[word].push_back(Posting{slot, weight});
  }
  slot_of_[keyframe] = slot;
}

bool KeyframeDatabase::Erase(KeyframeId keyframe) {
  std::unique_lock lock(mutex_);
  const bool known = slot_of_.count(keyframe) > 0;
  EraseLocked(keyframe);
  return known;
}

void KeyframeDatabase::EraseLocked(KeyframeId keyframe) {
  auto it = slot_of_.find(keyframe);
  if (it == slot_of_.end()) return;
  const std::uint32_t slot = it->second;
  Slot& s = slots_[slot];
  for (const auto& entry : s.bow.entries) {
    if (entry.first >= inverted_.size()) continue;
    auto& list = inverted_[entry.first];
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (list[i].slot == slot) {
        list[i] = list.back();
        list.pop_back();
        break;
      }
    }
  }
  s = Slot{};
  free_slots_.push_back(slot);
  slot_of_.erase(it);
}

std::size_t KeyframeDatabase::ReassignMap(MapId from, MapId to) {
  std::unique_lock lock(mutex_);
  std::size_t n = 0;
  for (auto& s : slots_) {
    if (s.alive && s.map == from) {
      s.map = to;
      ++n;
    }
  }
  return n;
}

void KeyframeDatabase::Clear() {
  std::unique_lock lock(mutex_);
  for (auto& list : inverted_) list.clear();
  slots_.clear();
  free_slots_.clear();
  slot_of_.clear();
}

std::size_t KeyframeDatabase::size() const {
  std::shared_lock lock(mutex_);
  return slot_of_.size();
}

bool KeyframeDatabase::Contains(KeyframeId keyframe) const {
  std::shared_lock lock(mutex_);
  return slot_of_.count(keyframe) > 0;
}

std::optional<BowVector> KeyframeDatabase::GetBow(KeyframeId keyframe) const {
  std::shared_lock lock(mutex_);
  auto it = slot_of_.find(keyframe);
  if (it == slot_of_.end()) return std::nullopt;
  return slots_[it->second].bow;
}

std::vector<QueryResult> KeyframeDatabase::Query(const BowVector& query, const QueryFilter& filter,
                                                 std::size_t max_results) const {
  std::shared_lock lock(mutex_);
  // Accumulate, per keyframe slot, the shared words and the L1 score terms over the common
  // words only: |q-k|_1 = 2 - sum_common(|q|+|k|-|q-k|) for L1-normalized vectors.
  std::vector<float> score(slots_.size(), 0.f);
  std::vector<std::uint32_t> common(slots_.size(), 0);
  std::vector<std::uint32_t> touched;
  for (const auto& [word, qw] : query.entries) {
    if (word >= inverted_.size()) continue;
    for (const Posting& p : inverted_[word]) {
      if (common[p.slot]++ == 0) touched.push_back(p.slot);
      score[p.slot] += std::fabs(qw) + std::fabs(p.weight) - std::fabs(qw - p.weight);
    }
  }
  const std::unordered_set<KeyframeId> excluded(filter.exclude_keyframes.begin(),
                                                filter.exclude_keyframes.end());
  std::vector<QueryResult> results;
  results.reserve(touched.size());
  for (std::uint32_t slot : touched) {
    const Slot& s = slots_[slot];
    if (!filter.only_maps.empty() && !ContainsValue(filter.only_maps, s.map)) continue;
    if (ContainsValue(filter.exclude_maps, s.map)) continue;
    if (!filter.only_agents.empty() && !ContainsValue(filter.only_agents, s.agent)) continue;
    if (excluded.count(s.keyframe)) continue;
    QueryResult r;
    r.keyframe = s.keyframe;
    r.map = s.map;
    r.agent = s.agent;
    r.score = std::clamp(0.5 * score[slot], 0.0, 1.0);
    r.common_words = static_cast<int>(common[slot]);
    results.push_back(r);
  }
  lock.unlock();
  if (max_results > 0 && results.size() > max_results) {
    std::partial_sort(results.begin(), results.begin() + static_cast<std::ptrdiff_t>(max_results),
                      results.end(), ByScore);
    results.resize(max_results);
  } else {
    std::sort(results.begin(), results.end(), ByScore);
  }
  return results;
}

std::vector<PlaceCandidate> KeyframeDatabase::DetectCandidates(
    const BowVector& query, const QueryFilter& filter, const CandidateOptions& options,
    const CovisibilityFn& covisibility) const {
  const std::vector<QueryResult> all = Query(query, filter);
  if (all.empty()) return {};
  int max_common = 0;
  for (const auto& r : all) max_common = std::max(max_common, r.common_words);
  const double min_common = options.min_common_ratio * max_common;
  std::unordered_map<KeyframeId, const QueryResult*> scored;
  for (const auto& r : all) {
    if (r.common_words >= min_common && r.score >= options.min_score) scored[r.keyframe] = &r;
  }
  // Group each candidate with its covisible neighbours that also scored (no lock held here).
  std::vector<PlaceCandidate> groups;
  double best_group = 0.0;
  for (const auto& r : all) {
    if (!scored.count(r.keyframe)) continue;
    PlaceCandidate g;
    g.best = r;
    g.group_score = r.score;
    if (covisibility && options.covisible_neighbours > 0) {
      for (KeyframeId n : covisibility(r.keyframe, options.covisible_neighbours)) {
        auto it = scored.find(n);
        if (it == scored.end()) continue;
        g.group_score += it->second->score;
        if (ByScore(*it->second, g.best)) g.best = *it->second;
      }
    }
    best_group = std::max(best_group, g.group_score);
    groups.push_back(g);
  }
  const double keep = options.group_ratio * best_group;
  std::vector<PlaceCandidate> out;
  std::unordered_set<KeyframeId> seen;
  std::stable_sort(groups.begin(), groups.end(), [](const PlaceCandidate& a, const PlaceCandidate& b) {
    return a.group_score > b.group_score;
  });
  for (const auto& g : groups) {
    if (g.group_score < keep) break;
    if (!seen.insert(g.best.keyframe).second) continue;
    out.push_back(g);
    if (options.max_results > 0 && static_cast<int>(out.size()) >= options.max_results) break;
  }
  return out;
}

double KeyframeDatabase::MinScore(const BowVector& query,
                                  const std::vector<KeyframeId>& neighbours) const {
  std::shared_lock lock(mutex_);
  double min_score = 1.0;
  for (KeyframeId kf : neighbours) {
    auto it = slot_of_.find(kf);
    if (it != slot_of_.end()) min_score = std::min(min_score, ScoreL1(query, slots_[it->second].bow));
  }
  return min_score;
}

}  // namespace ccm
