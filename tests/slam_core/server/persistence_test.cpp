// Saving and loading the map stack: the loaded stack equals the saved one (counts, poses and
// positions to 1e-9, associations, graph, handlers), corrupted or truncated files are
// refused with a clear message, and registration continues on the loaded stack.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "slam_core/common/checksum.h"
#include "slam_core/server/map_persistence.h"
#include "slam_core/server/stack_file.h"
#include "tests/slam_core/server/server_test_util.h"

namespace ccm {
namespace {

using testing::LoadSim;
using testing::SimVocabulary;
using testing::TempPath;

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

void ExpectEqualStacks(const ServerBackend& a, const ServerBackend& b) {
  const auto ma = a.Snapshot().maps, mb = b.Snapshot().maps;
  ASSERT_EQ(ma.size(), mb.size());
  for (size_t i = 0; i < ma.size(); ++i) {
    const Map& x = ma[i]->map();
    const Map& y = mb[i]->map();
    EXPECT_EQ(ma[i]->id(), mb[i]->id());
    ASSERT_EQ(x.num_keyframes(), y.num_keyframes());
    ASSERT_EQ(x.num_map_points(), y.num_map_points());
    EXPECT_EQ(ma[i]->anchors().size(), mb[i]->anchors().size());
    for (const auto& kf : x.keyframes()) {
      const auto other = y.keyframe(kf->id());
      ASSERT_NE(other, nullptr);
      const SE3 d = kf->world_from_cam().inverse() * other->world_from_cam();
      EXPECT_LT(d.translation().norm(), 1e-9);
      EXPECT_LT(1.0 - std::abs(d.rotation().w()), 1e-9);
      EXPECT_EQ(kf->map_points(), other->map_points());
      EXPECT_EQ(kf->covisibility(), other->covisibility());
      EXPECT_EQ(kf->parent(), other->parent());
      EXPECT_EQ(kf->loop_edges(), other->loop_edges());
      EXPECT_EQ(kf->features().descriptors, other->features().descriptors);
      EXPECT_EQ(kf->camera().intrinsics().fx, other->camera().intrinsics().fx);
    }
    for (const auto& mp : x.map_points()) {
      const auto other = y.map_point(mp->id());
      ASSERT_NE(other, nullptr);
      EXPECT_LT((mp->position() - other->position()).norm(), 1e-9);
      EXPECT_EQ(mp->observations(), other->observations());
      EXPECT_EQ(mp->descriptor(), other->descriptor());
    }
  }
  const auto ha = a.Snapshot().handlers, hb = b.Snapshot().handlers;
  ASSERT_EQ(ha.size(), hb.size());
  for (size_t i = 0; i < ha.size(); ++i) {
    EXPECT_EQ(ha[i].map, hb[i].map);
    EXPECT_EQ(ha[i].last_keyframe, hb[i].last_keyframe);
    EXPECT_DOUBLE_EQ(ha[i].scale, hb[i].scale);
    EXPECT_LT((ha[i].map_from_segment.translation() - hb[i].map_from_segment.translation()).norm(), 1e-12);
  }
}

TEST(Persistence, SaveLoadGivesAnEqualStackAndRegistrationContinues) {
  const auto sim = LoadSim("hall3");
  ASSERT_NE(sim, nullptr);
  // Two agents, so there are two maps (no overlap yet in 6 s) and two handlers.
  const testing::VoStream s0 = testing::RunVoStream(sim, 0, 0, 160);
  const testing::VoStream s1 = testing::RunVoStream(sim, 1, 0, 120);
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  const size_t half = s0.batches.size() / 2;
  for (size_t i = 0; i < half; ++i) backend.Submit(s0.batches[i]);
  for (const AgentBatch& b : s1.batches) backend.Submit(b);
  backend.ProcessAllQueued();
  ASSERT_GE(backend.Snapshot().Summaries().size(), 1u);

  const std::string path = TempPath("ccm_stack.bin");
  std::string error;
  ASSERT_TRUE(SaveBackend(backend, path, &error)) << error;
  auto loaded = LoadBackend(path, SimVocabulary(), ServerOptions{}, &error);
  ASSERT_NE(loaded, nullptr) << error;
  ExpectEqualStacks(backend, *loaded);

  // The restarted server takes the rest of the flight: it lands in the same map.
  const size_t before = loaded->Snapshot().AgentTrajectory(1).size();
  for (size_t i = half; i < s0.batches.size(); ++i) loaded->Submit(s0.batches[i]);
  loaded->ProcessAllQueued();
  const auto traj = loaded->Snapshot().AgentTrajectory(1);
  EXPECT_GT(traj.size(), before + 5);
  for (const auto& p : traj) EXPECT_EQ(p.map, traj.front().map) << "the agent's segment stays in its map";
  std::remove(path.c_str());
}

TEST(Persistence, CorruptedTruncatedAndForeignFilesAreRefused) {
  const auto sim = LoadSim("hall3");
  const testing::VoStream s = testing::RunVoStream(sim, 0, 0, 60);
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  for (const AgentBatch& b : s.batches) backend.Submit(b);
  backend.ProcessAllQueued();
  const std::string path = TempPath("ccm_stack_bad.bin");
  std::string error;
  ASSERT_TRUE(SaveBackend(backend, path, &error)) << error;
  const std::string bytes = ReadBytes(path);
  auto write = [&](const std::string& content) { WriteBytes(path, content); };
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  write(flipped);
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr);
  EXPECT_NE(error.find("checksum"), std::string::npos) << error;
  write(bytes.substr(0, bytes.size() - 100));
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr);
  EXPECT_NE(error.find("size mismatch"), std::string::npos) << error;
  write("not a map stack at all");
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr);
  EXPECT_NE(error.find("not a ccm map stack"), std::string::npos) << error;
  std::remove(path.c_str());
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr);
  EXPECT_NE(error.find("cannot open"), std::string::npos) << error;
}

TEST(Persistence, ACorruptNewestGenerationFallsBackToThePreviousOne) {
  // A save keeps the file it replaces as path.prev; a newest file that no longer reads (a
  // disk error, a crash of the storage underneath) costs one generation, not the map.
  const auto sim = LoadSim("hall3");
  ASSERT_NE(sim, nullptr);
  const testing::VoStream s = testing::RunVoStream(sim, 0, 0, 80);
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  const size_t half = s.batches.size() / 2;
  for (size_t i = 0; i < half; ++i) backend.Submit(s.batches[i]);
  backend.ProcessAllQueued();
  const std::string path = TempPath("ccm_stack_generations.bin");
  const std::string prev = path + ".prev";
  std::remove(prev.c_str());
  std::string error, warning;
  ASSERT_TRUE(SaveBackend(backend, path, &error)) << error;
  EXPECT_FALSE(std::ifstream(prev).good());  // nothing to keep the first time
  const size_t first_keyframes = backend.Snapshot().Summaries().at(0).keyframes;
  for (size_t i = half; i < s.batches.size(); ++i) backend.Submit(s.batches[i]);
  backend.ProcessAllQueued();
  ASSERT_TRUE(SaveBackend(backend, path, &error)) << error;
  const size_t second_keyframes = backend.Snapshot().Summaries().at(0).keyframes;
  ASSERT_GT(second_keyframes, first_keyframes);

  auto newest = LoadBackend(path, SimVocabulary(), ServerOptions{}, &error, &warning);
  ASSERT_NE(newest, nullptr) << error;
  EXPECT_TRUE(warning.empty()) << warning;
  EXPECT_EQ(newest->Snapshot().Summaries().at(0).keyframes, second_keyframes);

  std::string bytes = ReadBytes(path);
  bytes[bytes.size() / 2] ^= 0x01;
  WriteBytes(path, bytes);
  auto fallback = LoadBackend(path, SimVocabulary(), ServerOptions{}, &error, &warning);
  ASSERT_NE(fallback, nullptr) << error;
  EXPECT_NE(warning.find("checksum"), std::string::npos) << warning;
  EXPECT_NE(warning.find(".prev"), std::string::npos) << warning;
  EXPECT_EQ(fallback->Snapshot().Summaries().at(0).keyframes, first_keyframes);

  // Both generations unreadable: a clear error naming both.
  WriteBytes(prev, "garbage");
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error, &warning), nullptr);
  EXPECT_NE(error.find("previous generation too"), std::string::npos) << error;
  std::remove(path.c_str());
  std::remove(prev.c_str());
}

TEST(Persistence, AFileWhoseObservationsPointOutsideTheKeypointsIsRefused) {
  // The checksum protects against accidents, not against a crafted file (FNV is no MAC):
  // the loader itself must refuse indices that optimization would follow out of bounds.
  const auto sim = LoadSim("hall3");
  ASSERT_NE(sim, nullptr);
  const testing::VoStream s = testing::RunVoStream(sim, 0, 0, 60);
  ServerBackend backend(SimVocabulary(), ServerOptions{});
  for (const AgentBatch& b : s.batches) backend.Submit(b);
  backend.ProcessAllQueued();
  const std::string path = TempPath("ccm_stack_crafted.bin");
  std::string error;
  ASSERT_TRUE(SaveBackend(backend, path, &error)) << error;
  ASSERT_NE(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr) << error;

  const auto smap = backend.Snapshot().maps.at(0);
  const auto mp = smap->map().map_points().front();
  std::shared_ptr<KeyFrame> kf;
  for (const auto& k : smap->map().keyframes()) {
    if (!mp->KeypointIn(k->id())) kf = k;  // one that does not observe it yet
  }
  ASSERT_NE(kf, nullptr);
  ASSERT_TRUE(mp->AddObservation(kf->id(), static_cast<int>(kf->num_keypoints()) + 7));  // bypasses the Map
  ASSERT_TRUE(SaveBackend(backend, path, &error)) << error;
  std::remove((path + ".prev").c_str());  // no fallback: the crafted file alone
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr);
  EXPECT_NE(error.find("outside its keyframe's keypoints"), std::string::npos) << error;
  std::remove(path.c_str());
}

TEST(Persistence, ASizeFieldClaimingMillionsOfElementsAllocatesNothing) {
  // A crafted payload (checksum recomputed) whose first vector, the cameras, claims 2^24
  // elements and then ends. cereal would resize to the claim first (~1.3 GB of records); the
  // loader must fail on the missing bytes without allocating for elements that are not there.
  std::string payload;
  auto put = [&](uint64_t v, size_t bytes) { payload.append(reinterpret_cast<const char*>(&v), bytes); };
  put(1, 1);          // portable binary: little-endian data
  put(1, 8);          // next_map
  put(1ull << 24, 8);  // cameras: size tag
  put(1, 4);          // half of a first camera, then nothing
  const uint32_t version = kMapStackVersion;
  const uint64_t size = payload.size();
  const uint64_t checksum = Fnv1a64(reinterpret_cast<const uint8_t*>(payload.data()), payload.size());
  const std::string path = TempPath("ccm_stack_huge_claim.bin");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(kMapStackMagic, sizeof(kMapStackMagic));
    out.write(reinterpret_cast<const char*>(&version), sizeof(version));
    out.write(reinterpret_cast<const char*>(&size), sizeof(size));
    out << payload;
    out.write(reinterpret_cast<const char*>(&checksum), sizeof(checksum));
  }
  rusage before{}, after{};
  getrusage(RUSAGE_SELF, &before);
  std::string error;
  EXPECT_EQ(LoadBackend(path, SimVocabulary(), ServerOptions{}, &error), nullptr);
  getrusage(RUSAGE_SELF, &after);
  EXPECT_NE(error.find("cannot decode"), std::string::npos) << error;
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 200 * 1024) << "peak RSS grew by " << after.ru_maxrss - before.ru_maxrss
                                                            << " kB";
  std::remove(path.c_str());
}

}  // namespace
}  // namespace ccm
