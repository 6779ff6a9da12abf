// One agent's recorded keyframe stream (what ccm_replay --record and bench_fusion --record
// keep: the AgentBatches its ChangePacker made) as an AgentDataSource, so an AgentComm puts
// it on the wire as a real agent would: at its recorded pace, with the server's acks,
// resends of anything unacknowledged and the server's map data coming back. ccm_fleet
// (tools/fleet) runs many of these in one process to load a real ccm_server with a team no
// machine could fly with live VOs (issue 30). There is no VO behind it: server map data is
// counted, not integrated, and the stream cannot react to it.
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <set>
#include <unordered_map>
#include <vector>

#include "agent_runtime/agent_data_source.h"

namespace ccm::agent {

/// Renames agents in every id of `batch` (batch, keyframes, points, links, updates, segments)
/// whose agent is a key of `to`; ids of other agents stay. Two copies of one recording played
/// under different agent ids then never share an id.
void RemapAgents(const std::map<AgentId, AgentId>& to, AgentBatch* batch);

class RecordedDataSource : public AgentDataSource {
 public:
  using Clock = std::chrono::steady_clock;
  /// `batches`: one agent's, in recorded order. A batch is due once `speed` x the wall time
  /// since `start` reaches its stamp minus `t0_ns` (the recording's first stamp, shared by
  /// its agents so they keep their relative timing).
  RecordedDataSource(std::vector<AgentBatch> batches, int64_t t0_ns, Clock::time_point start, double speed);

  /// Every due batch of one segment merged (a later segment waits for the next call), with
  /// the keyframes asked for again in front. `now_ns` and `flush` are not used: the
  /// recording's own stamps stay in the batch.
  AgentBatch TakeBatch(int64_t now_ns, bool flush) override;
  bool Resend(KeyframeId id) override;
  void ApplyServerData(ServerMapData data) override;
  Counters counters() const override;

  /// Any thread: every batch has been taken.
  bool finished() const { return next_.load() >= batches_.size(); }
  /// Any thread: map data from the server (map sharing), counted.
  uint64_t server_keyframes_received() const { return server_keyframes_.load(); }
  uint64_t server_points_received() const { return server_points_.load(); }
  /// Recorded seconds of this agent's stream (first to last batch).
  double duration_s() const { return duration_s_; }

 private:
  bool Due(const AgentBatch& b, Clock::time_point now) const;

  std::vector<AgentBatch> batches_;
  int64_t t0_ns_;
  Clock::time_point start_;
  double speed_;
  double duration_s_ = 0.0;
  std::atomic<size_t> next_{0};
  std::unordered_map<KeyframeId, KeyframeData> sent_;  ///< every keyframe taken, for resends
  std::vector<KeyframeId> resend_;
  int64_t keyframes_taken_ = 0;
  size_t keyframes_left_ = 0;  ///< in batches not taken yet
  size_t anchors_taken_ = 0;
  std::atomic<uint64_t> server_keyframes_{0}, server_points_{0};
};

}  // namespace ccm::agent
