// The server's communication module: the DDS side of ccm_server. One comm thread (owned
// here, Start/Stop) does all of it, so DDS receive threads never wait on SLAM work:
//  * intake: the readers' listeners only enqueue (bounded queues; runtime_common/
//    typed_endpoints.h). The comm thread pops, converts and validates every message
//    (conv::FromMsg: a rejection is counted and logged once per kind; a message whose agent
//    id is not the one of its writer's partition agent_<id> is dropped: docs/security.md), admits agents
//    (protocol version, max_agents), groups each agent's data per map segment into an
//    AgentBatch and submits it to the back-end, whose bounded per-agent queue decouples the
//    agent's handler thread (BackendRunner). A slow handler therefore only fills its own
//    queue; a batch beyond it is dropped and counted, and the agent resends every keyframe
//    the server never acknowledged (with its points: ChangePacker::Resend).
//  * outgoing, every 1/publish_rate_hz per agent: a small acks-only ServerToAgent (each ack
//    repeated ack_repeats times: the topic may be BEST_EFFORT) and, when map sharing is on
//    and the agent's reference keyframe moved, a separate message with the k keyframes most
//    covisible with it. Two messages, and two writers (profiles ccm_server_ack_writer and
//    ccm_server_writer), because a 200 kB neighbourhood fragments into ~150 datagrams: on a
//    reliable topic, acks written after it waited until it was repaired or replaced (at 50 %
//    loss an agent got 24 messages in 60 s and left keyframes unacked). A new neighbourhood
//    does not replace one the agent has not received yet for kNeighbourhoodPatience, so a
//    lossy link delivers an older neighbourhood instead of none.
//  * durable acks (docs/protocol.md "Epochs and persisted acks"): every message carries this
//    start's epoch; ack messages are numbered; the daemon's autosave reports which numbers
//    its map file covers (OnPersisted), and the acks writer repeats that at least every
//    kAckHeartbeat, so an agent learns of a restart and of each save even when idle.
//  * reassembly (KeyframeReassembly, keyframe_reassembly.h): keyframes wait for their points,
//    updates that overtook their data are kept, resends of held keyframes replace them.
//  * no polling: the readers signal one Wakeup; the comm thread sleeps until a sample
//    arrives, an agent's next publish time, or a held keyframe's deadline.
//  * liveliness: an agent that sent nothing (heartbeat included) for liveliness_timeout_s has
//    left; its maps stay, and it is logged when it returns. Once it has been silent for
//    agent_slot_release_s, a new agent beyond max_agents takes its slot (its link, writers
//    and reassembly state go; the back-end frees its queue the same way).
// Stats() and the counters are readable from any thread.
#pragma once

#include <atomic>
#include <chrono>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/msg_conversion.h"
#include "runtime_common/typed_endpoints.h"
#include "runtime_common/wakeup.h"
#include "server_runtime/downlink_deltas.h"
#include "server_runtime/keyframe_reassembly.h"
#include "server_runtime/server_config.h"
#include "slam_core/server/server_backend.h"

namespace ccm::server {

/// What the server knows about one agent's link (its own heartbeat counters included).
struct AgentLink {
  int64_t keyframes = 0, map_points = 0, keyframe_updates = 0, map_point_updates = 0;
  int64_t status_msgs = 0;
  int64_t rejected = 0;               ///< messages that failed validation
  int64_t batches_submitted = 0, batches_dropped = 0;
  int64_t messages_sent = 0, neighbourhoods_sent = 0;
  int64_t neighbourhoods_deferred = 0;  ///< publish cycles that kept an undelivered one
  int64_t neighbourhood_keyframes_full = 0;      ///< keyframes sent with their features
  int64_t neighbourhood_keyframes_as_poses = 0;  ///< sent as poses only (the agent holds them)
  int64_t neighbourhood_points_full = 0;
  int64_t neighbourhood_points_as_positions = 0;  ///< sent as positions only (the agent holds them)
  int64_t keyframes_released_incomplete = 0;  ///< held the maximum time, some points still missing
  KeyframeId reference_kf;
  MapId segment;
  std::set<MapId> segments;           ///< every segment seen (a restart or tracking loss adds one)
  int64_t segments_not_listed = 0;    ///< named beyond kMaxSegmentsListed
  bool alive = false;
  int leaves = 0;                     ///< times it went silent for liveliness_timeout_s
  double last_seen_s = 0.0;           ///< since the comm module started
  // From its last heartbeat.
  uint32_t kfs_created = 0, kfs_sent = 0, kfs_acked = 0, kfs_resent = 0, kfs_lost = 0;
  int tracking_state = 0;
};

/// Segments listed per agent: a hostile agent naming a fresh segment in every message must
/// not grow the server's statistics without end (the back-end refuses data beyond its own
/// per-agent segment budget, ServerOptions::max_segments_per_agent).
inline constexpr size_t kMaxSegmentsListed = 256;
/// Adds `segment` to link->segments, or counts it once the list holds kMaxSegmentsListed.
void NoteSegment(MapId segment, AgentLink* link);
/// A validated heartbeat (conv::FromMsg) into what the server knows about the agent.
void ApplyStatus(const conv::AgentStatusData& status, AgentLink* link);

struct ServerCommStats {
  std::map<AgentId, AgentLink> agents;
  int64_t refused_agents = 0;         ///< messages from agents beyond max_agents
  int64_t released_agents = 0;        ///< silent agents whose slot went to a new agent
  int64_t rejected = 0;
  std::map<std::string, int64_t> rejected_by_kind;
  /// Messages whose agent id is not the one of the partition they were written in
  /// (another participant claiming to be that agent; with security: impossible to match).
  int64_t wrong_partition = 0;
  double elapsed_s = 0.0;
  double last_data_s = -1.0;          ///< last keyframe/point/update received (-1: none yet)
};

class ServerComm {
 public:
  /// `backend` must outlive the comm module; submitting to it is thread-safe.
  static std::unique_ptr<ServerComm> Create(const ServerConfig& config, rt::SessionOptions session_options,
                                            ServerBackend* backend, std::string* error);
  ~ServerComm();
  void Start();
  void Stop();
  ServerCommStats Stats() const;
  std::vector<rt::TopicCountersSnapshot> Traffic() const { return session_->TrafficSnapshot(); }
  /// The participant, for the daemon's own writers (status topic); same lifetime as this.
  rt::DdsSession& session() { return *session_; }

  /// This start's epoch (its wall-clock start time in ns).
  uint64_t epoch() const { return epoch_; }
  /// The newest ack message number written. Read it before taking a snapshot to save: the
  /// acks of messages up to it are for keyframes the snapshot holds.
  uint64_t AckSeqIssued() const { return ack_seq_issued_.load(); }
  /// The saved map file holds the acks of every message numbered <= `seq`. Any thread.
  void OnPersisted(uint64_t seq);
  /// Without a map file (save_map empty) nothing is ever persisted: acks are final at once.
  bool persists() const { return !config_.save_map.empty(); }

 private:
  struct PendingAck {
    uint64_t id;
    int repeats_left;
  };
  struct AgentState {  // comm thread only
    std::deque<PendingAck> kf_acks, mp_acks;
    KeyframeId shared_ref;  ///< reference keyframe of the last neighbourhood sent
    std::chrono::steady_clock::time_point next_publish;
    std::chrono::steady_clock::time_point last_neighbourhood;  ///< when it was written
    std::chrono::steady_clock::time_point last_ack_message;   ///< when the last acks message was written
    uint64_t persisted_sent = 0;  ///< persisted_seq in it
    DownlinkDeltas deltas;  ///< what the agent holds of the server's map
  };
  /// An agent hears from the acks writer at least this often (epoch, persisted_seq).
  static constexpr std::chrono::seconds kAckHeartbeat{1};
  /// The stamp of the next message to an agent; `with_acks` numbers it.
  conv::ServerAckStamp NextAckStamp(bool with_acks);
  /// One agent's writers, both in its partition (rt::AgentPartition) on ccm/server_to_agent:
  /// separate reliable streams, so acks never queue behind a neighbourhood under repair.
  struct AgentWriters {
    std::unique_ptr<rt::TypedWriter<msg::ServerToAgentPubSubType>> acks, neighbourhoods;
  };
  /// A neighbourhood the agent has not acknowledged (DDS-level) is replaced by a newer one
  /// only after this long.
  static constexpr std::chrono::seconds kNeighbourhoodPatience{5};
  /// Creates `agent`'s writers on first use; false (logged) if DDS refused.
  bool EnsureWriters(AgentId agent);
  ServerComm(ServerConfig config, std::unique_ptr<rt::DdsSession> session, ServerBackend* backend);
  void Run();
  /// When the comm thread must look again without new samples: the next agent's publish
  /// time, a held keyframe's deadline, at most kMaxIdle from now.
  std::chrono::steady_clock::time_point NextWake() const;
  bool Intake();  // returns whether anything arrived
  /// Pops up to `max` samples of `reader`; each from a valid agent id in its own partition
  /// goes to handle(agent, msg). Returns whether anything was popped.
  template <typename Reader, typename Handler>
  bool Drain(Reader& reader, int max, const char* what, Handler&& handle);
  void OnStatus(AgentId agent, const msg::AgentStatus& st);
  void OnKeyframe(AgentId agent, const msg::KeyframeFull& m);
  void OnPoints(AgentId agent, const msg::MapPointBatch& m, BatchSet* batches);
  void OnKeyframeUpdate(AgentId agent, const msg::KeyframeUpdate& m, BatchSet* batches);
  void OnPointUpdates(AgentId agent, const msg::MapPointUpdateBatch& m, BatchSet* batches);
  bool Admit(AgentId agent, const char* what);
  /// Drops the links of agents silent for agent_slot_release_s (mutex_ held); their ids.
  std::vector<AgentId> ReleaseIdleAgentsLocked();
  void Reject(AgentId agent, const std::string& reason);
  /// True when `writer` writes in agent `agent`'s partition; otherwise counted and false.
  bool FromItsPartition(const eprosima::fastrtps::rtps::GUID_t& writer, AgentId agent, const char* what);
  void SubmitBatches(BatchSet* batches);
  void PublishToAgents();
  void CheckLiveliness();
  double Elapsed() const;

  const ServerConfig config_;
  std::unique_ptr<rt::DdsSession> session_;  // destroyed last (declared first)
  ServerBackend* backend_;
  rt::Wakeup wakeup_;  // signalled by every reader and by Stop(); declared before the readers, which use it
  std::unique_ptr<rt::TypedReader<msg::KeyframeFullPubSubType>> keyframe_reader_;
  std::unique_ptr<rt::TypedReader<msg::MapPointBatchPubSubType>> point_reader_;
  std::unique_ptr<rt::TypedReader<msg::KeyframeUpdatePubSubType>> kf_update_reader_;
  std::unique_ptr<rt::TypedReader<msg::MapPointUpdateBatchPubSubType>> mp_update_reader_;
  std::unique_ptr<rt::TypedReader<msg::AgentStatusPubSubType>> status_reader_;
  /// Per agent, in that agent's partition: created when the agent is first heard of, so its
  /// messages reach it alone.
  std::map<AgentId, AgentWriters> writers_;

  // Comm thread.
  conv::CameraCache cameras_;
  std::map<AgentId, AgentState> states_;
  KeyframeReassembly reassembly_;
  std::set<std::string> logged_kinds_;
  std::set<AgentId> refused_logged_;

  const std::chrono::steady_clock::time_point start_;
  const uint64_t epoch_;
  std::atomic<uint64_t> ack_seq_issued_{0};
  std::atomic<uint64_t> persisted_seq_{0};
  mutable std::mutex mutex_;  // guards stats_; leaf
  ServerCommStats stats_;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace ccm::server
