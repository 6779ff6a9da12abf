// Fuzz test of map stack files (issue 28): mutated copies of a real file (two agents' maps
// of hall3), with the checksum recomputed (FNV is no MAC: anyone who can write the file can
// forge it), go through MapPersistence::Load, the server's start-up path. No crash; every
// file is either refused with a message or loads contents that pass a validity check written
// here, independently of the loader (what optimization, matching and registration index or
// compute with: levels, keypoints, observations, finite poses and positions, handlers, ids);
// no single allocation above kAllocationCap while loading. A sample of the accepted files
// also goes through LoadBackend (the place-recognition database is rebuilt from the
// keyframes) and is saved and loaded again. Inputs: CCM_FUZZ_INPUTS, 2,000 in the normal run;
// deploy/run-sanitizer-tests.sh runs 100,000 under ASan + UBSan.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <new>
#include <set>

#include "slam_core/common/checksum.h"
#include "slam_core/server/map_persistence.h"
#include "slam_core/server/stack_file.h"
#include "tests/fuzz_inputs.h"
#include "tests/slam_core/server/map_file_mutator.h"
#include "tests/slam_core/server/server_test_util.h"

// A counting allocator for this test binary: the largest single request while g_track is
// set. Every unaligned form is replaced, so each pair allocates and frees alike (under ASan
// an unreplaced form would be ASan's own, and mixing the two is an alloc-dealloc mismatch);
// memory itself comes from malloc, so ASan still checks every access.
namespace {
std::atomic<bool> g_track{false};
std::atomic<size_t> g_largest{0};

void* CountedAlloc(size_t n) noexcept {
  if (g_track.load(std::memory_order_relaxed)) {
    size_t seen = g_largest.load(std::memory_order_relaxed);
    while (n > seen && !g_largest.compare_exchange_weak(seen, n, std::memory_order_relaxed)) {
    }
  }
  return std::malloc(n ? n : 1);
}
void* CountedAllocOrThrow(size_t n) {
  if (void* p = CountedAlloc(n)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(size_t n) { return CountedAllocOrThrow(n); }
void* operator new[](size_t n) { return CountedAllocOrThrow(n); }
void* operator new(size_t n, const std::nothrow_t&) noexcept { return CountedAlloc(n); }
void* operator new[](size_t n, const std::nothrow_t&) noexcept { return CountedAlloc(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }
void operator delete[](void* p, size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

namespace ccm {
namespace {

// The loader reads the whole file into one string and copies the payload out of it; the
// base file is ~0.75 MB. Nothing a file claims may make it ask for more than this at once.
constexpr size_t kAllocationCap = 16u << 20;

bool UnitRotation(const Eigen::Quaterniond& q) {
  const double n = q.norm();
  return std::isfinite(n) && std::abs(n - 1.0) < 1e-6;
}
bool ValidPose(const SE3& T) { return UnitRotation(T.rotation()) && T.translation().allFinite(); }

// The first reason the loaded contents are unusable, or "" when they are valid.
std::string Violation(const RestoredStack& restored) {
  MapStackSnapshot c = MapStackSnapshot::Of(*restored.stack);
  c.events = restored.events;
  std::set<MapId> maps;
  std::set<KeyframeId> keyframes;
  std::set<MapPointId> points;
  for (const auto& smap : c.maps) {
    if (!smap || !maps.insert(smap->id()).second) return "map id repeated";
    // New maps get MapId::Make(0, next_map_counter++): a file's counter below one of its maps
    // would hand that id out again.
    if (smap->id().agent() != kServerAgent || !smap->id().valid() || smap->id().counter() >= c.next_map_counter) {
      return "map id outside the server's map ids";
    }
    const Map& map = smap->map();
    for (const auto& kf : map.keyframes()) {
      const std::string id = "keyframe " + std::to_string(kf->id().packed());
      if (!kf->id().valid() || !keyframes.insert(kf->id()).second) return id + ": invalid or repeated id";
      const CameraIntrinsics& cam = kf->camera().intrinsics();
      if (!ValidateIntrinsics(cam).empty()) return id + ": camera";
      const ScalePyramid& pyr = kf->pyramid();
      if (pyr.num_levels < 1 || pyr.num_levels > 16 || !(pyr.scale_factor > 1.0 && pyr.scale_factor <= 2.0)) {
        return id + ": pyramid";
      }
      const FrameFeatures& f = kf->features();
      if (f.descriptors.size() != f.keypoints.size() || kf->map_points().size() != f.keypoints.size()) {
        return id + ": feature counts";
      }
      for (const Keypoint& k : f.keypoints) {
        if (k.level < 0 || k.level >= pyr.num_levels) return id + ": keypoint level";
        if (!(k.u >= 0 && k.u <= cam.width_px && k.v >= 0 && k.v <= cam.height_px) || !std::isfinite(k.angle_deg) ||
            !std::isfinite(k.response)) {
          return id + ": keypoint outside the image or not finite";
        }
      }
      if (!ValidPose(kf->world_from_cam())) return id + ": pose";
      if (const auto info = smap->Info(kf->id())) {
        if (!ValidPose(info->pred_from_cam) || !ValidPose(info->parent_from_cam) || !ValidPose(info->segment_from_cam)) {
          return id + ": relative poses";
        }
      }
    }
    for (const auto& mp : map.map_points()) {
      const std::string id = "map point " + std::to_string(mp->id().packed());
      if (!mp->id().valid() || !points.insert(mp->id()).second) return id + ": invalid or repeated id";
      if (!mp->position().allFinite() || !mp->normal().allFinite()) return id + ": position or normal";
      if (!(mp->min_distance_m() >= 0 && mp->max_distance_m() >= mp->min_distance_m() &&
            std::isfinite(mp->max_distance_m()))) {
        return id + ": distances";
      }
      for (const auto& [kf_id, index] : mp->observations()) {
        const auto kf = map.keyframe(kf_id);
        if (!kf) return id + ": observed by a keyframe not in its map";
        if (index < 0 || static_cast<size_t>(index) >= kf->num_keypoints()) return id + ": observation index";
      }
    }
    for (const auto& [id, a] : smap->anchors()) {
      if (!ValidPose(a.base_from_cam)) return "anchor " + std::to_string(id.packed()) + ": pose";
    }
  }
  if (c.next_map_counter > MapId::kCounterMask) return "next map counter beyond the id space";
  for (const AgentHandler& h : c.handlers) {
    if (!maps.count(h.map)) return "handler points to a missing map";
    const Sim3& S = h.map_from_segment;
    if (!(S.scale() > 0 && std::isfinite(S.scale())) || !UnitRotation(S.rotation()) || !S.translation().allFinite()) {
      return "handler Sim(3)";
    }
    if (!(h.scale > 0 && std::isfinite(h.scale))) return "handler scale";
  }
  for (const ServerEvent& e : c.events) {
    const int kind = static_cast<int>(e.kind);
    if (kind < 0 || kind > static_cast<int>(ServerEvent::Kind::kGlobalBa)) return "event kind";
  }
  return "";
}

void WriteFile(const std::string& path, const std::string& payload) {
  const uint32_t version = kMapStackVersion;
  const uint64_t size = payload.size();
  const uint64_t checksum = Fnv1a64(reinterpret_cast<const uint8_t*>(payload.data()), payload.size());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(kMapStackMagic, sizeof(kMapStackMagic));
  out.write(reinterpret_cast<const char*>(&version), sizeof(version));
  out.write(reinterpret_cast<const char*>(&size), sizeof(size));
  out << payload;
  out.write(reinterpret_cast<const char*>(&checksum), sizeof(checksum));
}

TEST(MapFileFuzz, MutatedFilesWithAValidChecksumAreRefusedWithAMessageOrLoadValid) {
  const auto sim = testing::LoadSim("hall3");
  ASSERT_NE(sim, nullptr);
  ServerBackend backend(testing::SimVocabulary(), ServerOptions{});
  // Small maps (the first batches of two flights, a few keyframes each, 500 features per
  // frame after initialization): each input is read, decoded and checked in a few ms, and
  // every field kind occurs.
  VoOptions vo;
  vo.orb.num_features = 500;
  for (int agent = 0; agent < 2; ++agent) {
    const auto stream = testing::RunVoStream(sim, agent, 0, 40, 5, vo);
    for (size_t i = 0; i < std::min<size_t>(3, stream.batches.size()); ++i) backend.Submit(stream.batches[i]);
  }
  backend.ProcessAllQueued();
  ASSERT_GE(backend.Snapshot().Summaries().size(), 2u);
  const std::string base_path = testing::TempPath("ccm_fuzz_base.bin"), path = testing::TempPath("ccm_fuzz_input.bin");
  const std::string resaved = testing::TempPath("ccm_fuzz_resaved.bin");
  std::string error, warning;
  ASSERT_TRUE(SaveBackend(backend, base_path, &error)) << error;
  const std::string file = [&] {
    std::ifstream in(base_path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  const size_t header = sizeof(kMapStackMagic) + 4 + 8;
  ASSERT_GT(file.size(), header + 8);
  const std::string payload = file.substr(header, file.size() - header - 8);
  const auto fields = testing::PayloadWalker::Walk(payload);
  ASSERT_TRUE(fields) << "the walker's layout no longer matches map_persistence.cc";

  // The unmutated file loads valid (the check itself passes real data).
  WriteFile(path, payload);
  g_largest = 0;
  g_track = true;
  const auto base = MapPersistence::Load(path, MapOptions{}, &error, &warning);
  g_track = false;
  ASSERT_TRUE(base) << error;
  ASSERT_EQ(Violation(*base), "");
  const size_t base_largest = g_largest;
  size_t keyframes = 0;
  for (const auto& m : base->stack->Maps()) keyframes += m->map().num_keyframes();
  std::cout << "base file: " << file.size() << " bytes, " << fields->size() << " fields, " << base->stack->num_maps()
            << " maps, " << keyframes << " keyframes, largest allocation " << base_largest << " bytes\n";

  const int total = testing::FuzzInputs(2000);
  testing::PayloadMutator mutate(20261128, payload, *fields);
  int accepted = 0, refused = 0, invalid = 0, backend_loads = 0, silent = 0;
  size_t largest = 0;
  std::map<std::string, int> reasons, violations;
  for (int i = 0; i < total; ++i) {
    if (i > 0 && i % 10000 == 0) {  // long sanitizer runs: where they are
      std::cout << i << " files so far: " << accepted << " loaded (" << invalid << " invalid), " << refused
                << " refused, largest allocation " << largest << " bytes" << std::endl;
    }
    WriteFile(path, mutate.Next());
    error.clear();
    g_largest = 0;
    g_track = true;
    const auto loaded = MapPersistence::Load(path, MapOptions{}, &error, &warning);
    g_track = false;
    largest = std::max<size_t>(largest, g_largest);
    if (!loaded) {
      ++refused;
      if (error.empty()) ++silent;
      // The reason without the path and numbers: "cannot decode", "keyframe ... inconsistent".
      std::string kind = error.substr(std::min(error.size(), path.size() + 2));
      for (char& ch : kind) ch = std::isdigit(static_cast<unsigned char>(ch)) ? '#' : ch;
      ++reasons[kind.substr(0, 70)];
      continue;
    }
    ++accepted;
    if (const std::string v = Violation(*loaded); !v.empty()) {
      ++invalid;
      ++violations[v.substr(v.find(':') == std::string::npos ? 0 : v.find(':'))];
      continue;
    }
    // A sample of the accepted files (every 50th, every 500th in a 100,000 run): the whole
    // start-up (database rebuilt), a save and a reload.
    if (accepted % std::max(50, total / 200) == 1) {
      ++backend_loads;
      auto restored = LoadBackend(path, testing::SimVocabulary(), ServerOptions{}, &error);
      ASSERT_NE(restored, nullptr) << "accepted by MapPersistence, refused by the back-end: " << error;
      ASSERT_TRUE(SaveBackend(*restored, resaved, &error)) << error;
      ASSERT_TRUE(MapPersistence::Load(resaved, MapOptions{}, &error, &warning)) << error;
    }
  }
  std::cout << total << " files: " << accepted << " loaded (" << invalid << " of them invalid), " << refused << " refused (" << reasons.size()
            << " kinds), " << backend_loads << " also through LoadBackend and a re-save; largest allocation "
            << largest << " bytes\n";
  for (const auto& [reason, count] : reasons) std::cout << "  " << count << "  " << reason << "\n";
  for (const auto& [v, count] : violations) std::cout << "  ACCEPTED INVALID " << count << "  " << v << "\n";
  EXPECT_EQ(invalid, 0) << "the loader accepted contents that fail the validity check";
  EXPECT_EQ(silent, 0) << "refusals without a message";
  EXPECT_LE(largest, kAllocationCap);
  EXPECT_GT(accepted, total / 20) << "the mutations should leave some files loadable";
  EXPECT_GT(refused, total / 4);
  for (const auto& p : {base_path, path, resaved, PreviousGeneration(resaved)}) std::remove(p.c_str());
}

}  // namespace
}  // namespace ccm
