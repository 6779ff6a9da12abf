// ccm_replay's engine: several agents' VO and the server back-end in one process, with the
// code paths of the real system minus DDS. Each agent's AgentVo tracks its frames; every
// send period (data time) its changes are packed (ChangePacker) and submitted to the
// ServerBackend; the server's acknowledgements feed the agent's bounded local map and the
// server's k covisible keyframes go back into the agent's VO (map sharing). Agents are
// interleaved by frame timestamp, so the server sees data in the order a live team produces.
// Deterministic mode runs everything on the caller's thread in a fixed order; threaded mode
// gives each agent its VO threads and the back-end its stage threads (BackendRunner).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "slam_core/io/frame_source.h"
#include "slam_core/io/trajectory.h"
#include "slam_core/map/near_duplicate.h"
#include "slam_core/server/server_backend.h"
#include "slam_core/vo/vo_options.h"
#include "server_runtime/run_report.h"

namespace ccm::replay {

using report::AgentRunResult;
using report::RunResult;

struct ReplayAgentInput {
  std::string name;
  AgentId id = 1;
  std::unique_ptr<FrameSource> source;
};

struct ReplayOptions {
  VoOptions vo;
  /// The agents' relocalization vocabulary (as ccm_agent's); null: brute force.
  std::shared_ptr<const Vocabulary> agent_vocabulary;
  ServerOptions server;
  double send_period_s = 0.25;   ///< agent -> server batches, data time (CCM-SLAM: 2-5 Hz)
  /// New keyframes leave once this old (data time), as ccm_agent does (ChangePacker).
  double new_keyframe_delay_s = 1.5;
  /// Near-duplicates leave as anchors only, as ccm_agent does (agent config
  /// anchor_duplicate_*; distance_ratio 0: every keyframe in full).
  NearDuplicateRule anchor_duplicates;
  bool map_sharing = true;       ///< server -> agent: k covisible keyframes each send period
  bool threaded = false;         ///< false: one thread, deterministic
  int64_t max_frames = -1;       ///< per agent (-1: all)
  bool final_global_ba = true;   ///< the end-of-run work (ServerBackend::ScheduleFinish)
  /// A link outage (the fault harness's --cut-at/--cut-s without DDS): from this long after
  /// an agent's first frame (data time; < 0: never) for link_cut_s, nothing goes to the
  /// server and nothing comes back (no acks, no map sharing); what the agent packed meanwhile
  /// arrives in one burst when the link returns, as the reliable writers deliver it.
  double link_cut_at_s = -1.0;
  double link_cut_s = 0.0;
  /// After the cut, the burst's points arrive this long after their keyframes (data time;
  /// 0: together), and those keyframes reach the back-end flagged as ccm_server's reassembly
  /// flags keyframes that left before their points (KeyframeData::points_incomplete): what
  /// DDS delivered after a minute's outage in the live fault harness.
  double link_cut_points_late_s = 0.0;
  double progress_period_s = 2.0;
  /// Sees every batch just before it is submitted (a Recording, a test probe). Threaded
  /// replays call it from the agents' threads, one at a time.
  std::function<void(const AgentBatch&)> on_batch;
  std::string Validate() const;
  /// The server options to build the back-end with: a deterministic replay runs global BA
  /// on one thread (multi-threaded Ceres sums in a different order on every run, and a
  /// last-bit difference changes which loops close later).
  ServerOptions BackendOptions() const {
    ServerOptions s = server;
    if (!threaded) s.optimization.global_ba_threads = 1;
    return s;
  }
};

/// Progress line data, sent every progress period.
struct ReplayProgress {
  double elapsed_s = 0.0;
  int64_t frames_done = 0, frames_total = 0;
  std::vector<MapSummary> maps;
  int64_t fusions = 0, loops = 0;
};

using ProgressFn = std::function<void(const ReplayProgress&)>;

/// Runs every agent to the end of its input. `backend` is the caller's (so it can be saved,
/// inspected or preloaded from a saved map); it must be empty or loaded, and not running.
RunResult RunReplay(std::vector<ReplayAgentInput> agents, const ReplayOptions& options, ServerBackend* backend,
                       const ProgressFn& progress = {});

}  // namespace ccm::replay
