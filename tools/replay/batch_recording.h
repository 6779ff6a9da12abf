// A recording of what the agents sent during a replay: every AgentBatch in submission order
// plus each agent's ground truth and VO keyframe trajectory. Played into a fresh back-end it
// reproduces the server's input without running the VO again, so tests and benchmarks can
// compare server settings (redundancy on/off, save/load half-way, N agents' load) on the
// same keyframe streams. File: magic "CCMRECRD", version, cereal portable binary payload,
// FNV-1a-64 checksum.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/exchange/agent_data.h"
#include "tools/replay/replay_session.h"

namespace ccm::replay {

struct RecordedAgent {
  std::string name;
  AgentId id = 0;
  int64_t frames = 0, frames_tracked = 0, keyframes_created = 0;
  int segments = 0;
  int64_t relocalizations = 0;
  Trajectory ground_truth;
  Trajectory vo_keyframes;
  std::map<MapId, Trajectory> vo_segments;
};

struct Recording {
  std::vector<RecordedAgent> agents;
  std::vector<AgentBatch> batches;  ///< in the order the server received them
};

/// The agents' part of a replay result (call after RunReplay filled `batches`).
void RecordAgents(const RunResult& result, Recording* recording);

bool SaveRecording(const Recording& recording, const std::string& path, std::string* error);
std::optional<Recording> LoadRecording(const std::string& path, std::string* error);

struct PlayOptions {
  size_t first = 0;             ///< batches [first, last) are submitted
  size_t last = static_cast<size_t>(-1);
  bool threaded = false;        ///< BackendRunner threads instead of ProcessAllQueued per batch
  /// Threaded: wait until the back-end is idle after every this many batches (0: submit all
  /// at once). A live server gets each agent's data at its publish rate, not a whole flight
  /// at once; dumped, one agent's handler races far ahead and cross-map detections, which
  /// need consecutive consistent queries, depend on that race.
  size_t threaded_window = 0;
  bool final_global_ba = true;
};

/// The recording's agents (ground truth, VO) with their keyframes in `backend`'s maps, as
/// EvaluateRun scores them (no wall time).
RunResult ResultFromBackend(const Recording& recording, const ServerBackend& backend);

/// Feeds the recorded batches into `backend` and returns a RunResult (agents' ground truth
/// and VO trajectories from the recording, server trajectories from the back-end), so
/// EvaluateRun scores it like a live replay.
RunResult PlayRecording(const Recording& recording, ServerBackend* backend, const PlayOptions& options);

}  // namespace ccm::replay
