// ccm_fleet's team: the agents of one or more recordings under fresh agent ids (1, 2, ...
// in recording order; a recording given twice is a second team on the same place), each
// with its own RecordedDataSource, AckTracker and AgentComm (own DDS participant). Owns the
// comm threads through the AgentComms (Connect starts them, Drain stops them).
#pragma once

#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "agent_runtime/ack_tracker.h"
#include "agent_runtime/agent_comm.h"
#include "agent_runtime/recorded_data_source.h"
#include "tools/replay/batch_recording.h"

namespace ccm::fleet {

struct TeamOptions {
  std::vector<std::string> recordings;
  size_t max_agents = 0;  ///< 0: all agents of all recordings
  double speed = 1.0;
  double stagger_s = 0.0;  ///< recording k starts k x this later
  /// Keep every batch in one recording too (Offline()): for ccm_fleet --offline only.
  bool keep_batches = false;
};

class Team {
 public:
  /// Loads the recordings and renames their agents; nullptr with a message on a bad file or
  /// more than 65535 agents.
  static std::unique_ptr<Team> Load(const TeamOptions& options, std::string* error);
  ~Team();

  size_t size() const { return members_.size(); }
  /// Wall seconds from the start to the end of the longest stream (stagger and speed included).
  double duration_s() const;
  /// Creates every agent's participant and starts its comm thread; the streams start at `start`.
  bool Connect(const agent::AgentConfig& config, const rt::SessionOptions& session,
               std::chrono::steady_clock::time_point start, std::string* error);
  /// Every batch of every stream taken.
  bool Finished() const;
  /// Waits until each agent's keyframes are acknowledged (at most `timeout` in all), then
  /// stops the comm threads. True if all were.
  bool Drain(std::chrono::milliseconds timeout);
  std::string ProgressLine() const;
  /// Per agent its link counters and traffic, plus totals (fleet.json).
  nlohmann::json Summary() const;
  /// The merged recording's agents with their keyframes in `backend`'s maps (--score).
  report::RunResult ResultFromMaps(const ServerBackend& backend) const;
  /// Every member's batches under its fleet id in the order of their start times (stagger
  /// and stamps), with the members' ground truth and VO: what ccm_replay's deterministic
  /// engine plays (--offline). Empty batches unless loaded with keep_batches.
  const replay::Recording& recording() const { return merged_; }
  /// Seconds from the last batch played to the last acknowledgement (after Drain).
  double drain_s() const { return drain_s_; }

 private:
  struct Member {
    AgentId id = 0;
    std::string name;
    size_t recording = 0;
    double stagger_s = 0.0;
    std::vector<AgentBatch> batches;  ///< until Connect hands them to the source
    int64_t t0_ns = 0;
    std::unique_ptr<agent::RecordedDataSource> source;
    std::unique_ptr<agent::AckTracker> acks;
    std::unique_ptr<agent::AgentComm> comm;  ///< last: stopped and destroyed first
  };
  /// The members' link counters summed (progress lines and fleet.json's totals).
  struct Totals {
    uint64_t sent = 0, acked = 0, unacked = 0, resent = 0, shared = 0, up = 0, down = 0;
    int matched = 0;
    double ack_p95_max = 0.0;
    std::vector<double> ack_medians;  ///< per agent, ascending
  };
  explicit Team(TeamOptions options) : options_(std::move(options)) {}
  Totals Sum() const;

  TeamOptions options_;
  replay::Recording merged_;  ///< ground truth and VO of every member, under its fleet id (no batches)
  std::vector<Member> members_;
  std::chrono::steady_clock::time_point started_;
  double drain_s_ = 0.0;
};

}  // namespace ccm::fleet
