// The agent's communication module (CCM-SLAM 4.5): every publish period it takes a batch
// from its data source (the VO's changes packed by a ChangePacker, or a recorded stream in
// the fleet tool: agent_data_source.h) and writes it (new keyframes and points in full on
// the RELIABLE topics, pose/position updates on the BEST_EFFORT ones, all relative), at most
// max_bytes_per_cycle, so a backlog after an outage leaves in
// several cycles instead of one burst. Server messages bring acknowledgements (AckTracker:
// KF i acked but not i-1 -> i-1 again in full; unacknowledged for ack_timeout -> again) and
// the server's k covisible keyframes, which go to the source (map sharing: the VO).
// Owns one thread (Start/Stop); the source and the AckTracker are the caller's and outlive it.
// Stats() and SetTrackingState() from any thread.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "agent_runtime/ack_tracker.h"
#include "agent_runtime/agent_data_source.h"
#include "agent_runtime/agent_config.h"
#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/msg_conversion.h"
#include "runtime_common/typed_endpoints.h"

namespace ccm::agent {

struct AgentCommStats {
  std::uint64_t kfs_sent = 0;          ///< first transmissions
  std::uint64_t kfs_sent_as_anchors = 0;  ///< of those, near-duplicates sent as pose anchors only
  std::uint64_t anchors_resent_in_full = 0;  ///< of those, resent in full under loss
  std::uint64_t kfs_resent = 0;
  std::uint64_t kfs_acked = 0;
  std::uint64_t kfs_unacked = 0;
  std::uint64_t mps_sent = 0;
  std::uint64_t kf_updates_sent = 0, mp_updates_sent = 0;
  std::uint64_t write_failures = 0;
  std::uint64_t server_msgs = 0;
  std::uint64_t server_msgs_rejected = 0;
  std::uint64_t server_keyframes_received = 0;
  std::uint64_t backlog_bytes = 0;     ///< packed but not written yet (rate limit)
  std::uint64_t deferred = 0;          ///< keyframes and points held for new_keyframe_delay_s
  double pack_ms_max = 0.0;            ///< longest TakeChanges + Pack (the VO map's exposure)
  double pack_ms_total = 0.0;
  std::uint64_t packs = 0;
  AckTracker::Latency ack_latency;     ///< first send -> ack (filled by Stats())
  std::uint64_t kfs_resent_gap = 0;    ///< of kfs_resent, by the gap rule (filled by Stats())
  int new_data_bytes_per_cycle = 0;    ///< the byte budget in use (NewDataBytesPerCycle; filled by Stats())
  // Durable acks (AckTracker; filled by Stats()).
  std::uint64_t kfs_persisted = 0;     ///< acknowledged and in the server's map file
  std::uint64_t kfs_unpersisted = 0;   ///< acknowledged, not saved yet (kept for a restarted server)
  std::uint64_t server_restarts = 0;   ///< newer server epochs seen after the first
  std::uint64_t kfs_resent_after_restart = 0;
  std::uint64_t server_msgs_stale = 0; ///< of an older epoch than the newest seen: ignored
};

class AgentComm {
 public:
  static std::unique_ptr<AgentComm> Create(const AgentConfig& config, rt::SessionOptions session_options,
                                           AgentDataSource* source, AckTracker* acks, std::string* error);
  ~AgentComm();

  void Start();
  /// Stops the thread after one last publish cycle.
  void Stop();
  AgentCommStats Stats() const;
  /// CPU seconds the comm thread used (packing, DDS writes, server data); valid after Stop().
  double cpu_seconds() const { return cpu_seconds_; }
  /// The tracking thread reports its state for the status heartbeat (0 initializing,
  /// 1 tracking, 2 lost).
  void SetTrackingState(int state) { tracking_state_ = state; }
  /// True once every keyframe sent was acknowledged and nothing is waiting to be written.
  bool Drained() const;
  /// Sends what the keyframe delay holds, then waits until Drained() or the timeout;
  /// returns Drained().
  bool WaitDrained(std::chrono::milliseconds timeout);
  std::vector<rt::TopicCountersSnapshot> Traffic() const { return session_->TrafficSnapshot(); }
  int matched_servers() const { return keyframe_writer_->matched(); }

 private:
  AgentComm(AgentConfig config, std::unique_ptr<rt::DdsSession> session, AgentDataSource* source, AckTracker* acks);
  void Run();
  void PackChanges();
  void WriteBacklog();
  void HandleServerMessage(const msg::ServerToAgent& message);
  void Resend(const std::vector<KeyframeId>& ids);
  void PublishStatus();

  AgentConfig config_;
  std::unique_ptr<rt::DdsSession> session_;  // destroyed last (declared first)
  AgentDataSource* source_;
  AckTracker* acks_;
  std::unique_ptr<rt::TypedWriter<msg::KeyframeFullPubSubType>> keyframe_writer_;
  std::unique_ptr<rt::TypedWriter<msg::MapPointBatchPubSubType>> point_writer_;
  std::unique_ptr<rt::TypedWriter<msg::KeyframeUpdatePubSubType>> kf_update_writer_;
  std::unique_ptr<rt::TypedWriter<msg::MapPointUpdateBatchPubSubType>> mp_update_writer_;
  std::unique_ptr<rt::TypedWriter<msg::AgentStatusPubSubType>> status_writer_;
  std::unique_ptr<rt::TypedReader<msg::ServerToAgentPubSubType>> server_reader_;

  // Comm-thread state.
  int bytes_per_cycle_ = 0;  ///< new data per cycle: max_bytes_per_cycle within the writers' cap
  conv::CameraCache cameras_;
  KeyframeId reference_kf_;
  MapId segment_;
  /// Packed messages waiting for the rate limit, oldest first (new data before updates of
  /// the same cycle).
  struct PackedKeyframe {
    msg::KeyframeFull message;
    bool resend = false;  ///< packed again for a resend (counted as kfs_resent when written)
  };
  std::deque<PackedKeyframe> kf_backlog_;
  struct PackedPoint {
    msg::MapPointFull message;
    MapId segment;  ///< goes in the batch header
  };
  std::deque<PackedPoint> mp_backlog_;
  std::vector<msg::KeyframeUpdate> kf_updates_;
  /// Keyframe updates are BEST_EFFORT: the latest pose of each keyframe goes out in
  /// kKeyframeUpdateCopies consecutive cycles (148 B each), so the last refinement of a
  /// keyframe, which no later update supersedes, survives a lossy link (20% -> 4% lost).
  static constexpr int kKeyframeUpdateCopies = 2;
  std::unordered_map<uint64_t, std::pair<msg::KeyframeUpdate, int>> kf_update_repeats_;
  std::vector<std::pair<msg::MapPointUpdate, MapId>> mp_updates_;
  std::vector<std::string> rejection_kinds_logged_;
  std::set<KeyframeId> resend_ids_;  ///< asked of the source since the last pack (cleared by it)
  std::uint64_t server_restarts_logged_ = 0;
  std::int64_t unpersisted_evictions_logged_ = 0;
  bool server_matched_ = false;    ///< keyframe writer and server reader both matched at the last check
  std::chrono::steady_clock::time_point server_matched_since_;  ///< when that began

  mutable std::mutex stats_mutex_;  // leaf
  std::condition_variable stats_cv_;  // notified after every cycle (WaitDrained)
  AgentCommStats stats_;
  std::atomic<int> tracking_state_{0};
  std::atomic<bool> flush_requested_{false};  ///< WaitDrained: pack everything, ignore the delay
  std::atomic<bool> running_{false};
  std::thread thread_;
  double cpu_seconds_ = 0.0;  ///< written by thread_ as it ends, read after the join
};

/// The link's counters as ccm_agent's JSON summary prints them ("link").
nlohmann::json LinkSummaryJson(const AgentComm& comm);

}  // namespace ccm::agent
