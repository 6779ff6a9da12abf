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

#include "server_runtime/backend_runner.h"
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

TEST(BackendRunnerSlots, AReleasedAgentsHandlerThreadEndsAndAReturningAgentGetsANewOne) {
  std::string error;
  auto vocab = LoadVocabularyFile(CCM_SIM_VOCAB_FILE, &error);
  ASSERT_TRUE(vocab) << error;
  ServerOptions options;
  options.max_agents = 1;
  options.agent_slot_release_s = 0.05;
  ServerBackend backend(std::make_shared<const Vocabulary>(std::move(*vocab)), options);
  BackendRunner runner(&backend);
  auto submit = [&](AgentId agent) {
    AgentBatch b;
    b.agent = agent;
    b.segment = MapId::Make(agent, 1);
    // An update of a point the server does not know: valid, ignored by registration.
    b.map_point_updates.push_back({MapPointId::Make(agent, 1), KeyframeId::Make(agent, 1), Eigen::Vector3d::Zero()});
    return backend.Submit(std::move(b));
  };
  auto batches_of = [&](AgentId agent) {
    const auto st = backend.Status().stats;
    return st.agents.count(agent) ? st.agents.at(agent).batches : 0;
  };
  ASSERT_EQ(submit(1), 0);
  backend.WaitUntilIdle();
  EXPECT_EQ(batches_of(1), 1);
  EXPECT_EQ(runner.num_threads(), 3u) << "place recognition, optimization, agent 1";
  EXPECT_EQ(submit(2), -1) << "one slot, held by agent 1";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_EQ(submit(2), 0) << "agent 1 has been silent for 100 ms > 50 ms";
  backend.WaitUntilIdle();
  EXPECT_EQ(batches_of(2), 1);
  EXPECT_EQ(backend.Status().stats.agent_slots_released, 1);
  for (int i = 0; i < 500 && runner.num_threads() != 3u; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(runner.num_threads(), 3u) << "agent 1's handler ended, agent 2's runs";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_EQ(submit(1), 0) << "agent 1 is back in agent 2's slot";
  backend.WaitUntilIdle();
  EXPECT_EQ(batches_of(1), 2) << "a new handler thread processed its batch";
  runner.Stop();
}

}  // namespace
}  // namespace ccm::server
