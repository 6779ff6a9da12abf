// The server's threads together, as ccm_server runs them: two simulated agents, each with its
// own tracking and mapping thread (AgentVo threaded), submit to the back-end's stages on
// BackendRunner threads (a handler per agent, place recognition, optimization), while a
// third thread does what ccm_server's main and map-view threads do meanwhile: refreshes the
// map view's snapshot, reads the statistics and autosaves the map stack. Every autosave must
// load back (a consistent snapshot of the whole stack), the view's version only grows, and at
// the end the view and the back-end agree. The ThreadSanitizer job (deploy/
// run-sanitizer-tests.sh tsan) runs it; in the normal run it takes a few seconds.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <iostream>
#include <filesystem>
#include <thread>

#include "server_runtime/map_view_snapshot.h"
#include "slam_core/place_recognition/vocabulary.h"
#include "slam_core/place_recognition/vocabulary_io.h"
#include "slam_core/server/map_persistence.h"
#include "slam_core/server/stack_file.h"
#include "tests/sim/sim_frame_source.h"
#include "tests/sim/simulation.h"
#include "tools/replay/replay_session.h"

namespace ccm::server {
namespace {

TEST(ThreadedPipeline, AgentsStagesMapViewAndAutosaveRunTogetherConsistently) {
  std::string error;
  const auto scenario = sim::LoadScenario("hall3", &error);
  ASSERT_TRUE(scenario) << error;
  const std::shared_ptr<const sim::Simulation> sim(sim::Simulation::Create(*scenario, &error));
  ASSERT_NE(sim, nullptr) << error;
  auto vocab = LoadVocabularyFile(CCM_SIM_VOCAB_FILE, &error);
  ASSERT_TRUE(vocab) << error;
  const auto vocabulary = std::make_shared<const Vocabulary>(std::move(*vocab));
  replay::ReplayOptions o;
  o.threaded = true;
  o.final_global_ba = true;  // the optimization thread runs at least once
  ServerBackend backend(vocabulary, o.BackendOptions());
  std::vector<replay::ReplayAgentInput> in;
  for (int a = 0; a < 2; ++a) {
    // 4 s of each flight at 10 Hz.
    in.push_back({sim->agent_name(a), static_cast<AgentId>(a + 1), std::make_unique<sim::SimFrameSource>(sim, a, 0, 2, 40)});
  }

  const std::string path =
      (std::filesystem::temp_directory_path() / ("ccm_threaded_pipeline_" + std::to_string(::getpid()))).string();
  MapViewModel view(&backend, MapViewOptions{});
  std::atomic<bool> flying{true};
  int refreshes = 0, saves = 0, loads = 0;
  uint64_t last_version = 0;
  bool version_went_back = false;
  std::string save_error;
  std::thread host([&] {
    while (flying) {
      view.Refresh();
      ++refreshes;
      const uint64_t v = view.Latest()->version;
      version_went_back |= v < last_version;
      last_version = v;
      (void)backend.Status();
      std::string e, w;
      if (!SaveBackend(backend, path, &e)) {
        save_error = e;
      } else {
        ++saves;
        loads += MapPersistence::Load(path, MapOptions{}, &e, &w).has_value();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  const report::RunResult r = replay::RunReplay(std::move(in), o, &backend);
  flying = false;
  host.join();
  ASSERT_EQ(r.error, "");

  EXPECT_EQ(save_error, "");
  EXPECT_GT(saves, 0);
  EXPECT_EQ(loads, saves) << "every autosave taken while the stages ran loads back";
  EXPECT_FALSE(version_went_back);
  ASSERT_EQ(r.agents.size(), 2u);
  size_t registered = 0;
  for (const auto& a : r.agents) {
    EXPECT_GT(a.keyframes_created, 3) << a.name;
    EXPECT_GT(a.server_keyframes.size(), 3u) << a.name << ": its keyframes reached the server's maps";
    registered += a.server_keyframes.size();
  }
  view.Refresh();
  size_t in_maps = 0;
  for (const MapSummary& m : backend.Snapshot().Summaries()) in_maps += m.keyframes;
  EXPECT_EQ(view.Latest()->keyframes.size(), in_maps) << "the view shows every keyframe of the maps";
  std::cout << refreshes << " view refreshes, " << saves << " autosaves (all load back) while " << registered
            << " keyframes were registered\n";
  std::remove(path.c_str());
  std::remove(PreviousGeneration(path).c_str());
}

}  // namespace
}  // namespace ccm::server
