// The middleware conversion layer: IDL wire types (idl/ccm_msgs.idl) <-> slam_core's exchange
// value types (slam_core/exchange/agent_data.h, server_map_data.h). The only code that sees
// both (docs/architecture.md). Pure functions: no DDS entities, no threads, no logging; the
// comm modules call them on their own threads.
//
// Relative coordinates (CCM-SLAM 4.5), all in the sending agent's VO scale [m]:
//  * KeyframeFull / KeyframeUpdate: pred_from_this = the keyframe's camera in its
//    predecessor's camera frame (KeyframeData::pred_from_cam); parent_from_this likewise for
//    the covisibility parent; segment_from_this = the VO pose in the segment's frame, which
//    the server uses only when neither predecessor nor parent is known.
//  * MapPointFull / MapPointUpdate: x/y/z_ref = position in the camera frame of the point's
//    reference keyframe (ref_kf_id).
//  * ServerToAgent: everything relative to the receiving agent's reference keyframe
//    (ref_kf_id) in that agent's VO scale: ref_from_this = a server keyframe's camera in the
//    reference keyframe's camera frame; point positions in that camera frame.
// Precision on the wire: poses double (exact round trip up to quaternion normalization);
// point positions, intrinsics, keypoints float.
//
// Receiving: FromMsg checks every field before anything can reach the back-end or the VO
// (protocol version, agent bits of every id, sizes and bounds, finite and sane numbers, unit
// quaternions within kQuaternionNormTolerance (then normalized), camera intrinsics, pyramid),
// then runs the exchange Validate* functions as the final gate. A rejection returns nullopt
// and a one-line reason "<kind>: <what>", e.g. "keyframe: keypoint 12 outside the image";
// ReasonKind() strips the numbers so a caller can log each kind once.
//
// Sending: ToMsg never exceeds an IDL bound; what does not fit is left out (see each function).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "idl/ccm_msgs.h"
#include "slam_core/exchange/agent_data.h"
#include "slam_core/exchange/server_map_data.h"

namespace ccm::conv {

/// |q| may differ from 1 by this much on the wire (float-rounded senders); beyond: rejected.
inline constexpr double kQuaternionNormTolerance = 1e-3;
/// Sanity bounds for received calibrations: beyond them projections are meaningless and
/// downstream code would compute with huge numbers.
inline constexpr double kMaxFocalLengthPx = 1e5;
inline constexpr double kMaxDistortionCoefficient = 1e4;

/// Shares one camera model per distinct calibration among received keyframes (a team has a
/// handful of cameras; every keyframe carries its calibration). Thread-compatible: one cache
/// per receiving thread. Holds at most `capacity` calibrations; the least recently used goes.
class CameraCache {
 public:
  explicit CameraCache(size_t capacity = 32) : capacity_(capacity == 0 ? 1 : capacity) {}
  /// The model for `intrinsics`; nullptr and *error if the calibration is not usable.
  std::shared_ptr<const CameraModel> Get(const CameraIntrinsics& intrinsics, std::string* error);
  size_t size() const { return entries_.size(); }

 private:
  struct Entry {
    CameraIntrinsics intrinsics;
    std::shared_ptr<const CameraModel> model;
    uint64_t last_use = 0;
  };
  const size_t capacity_;
  std::vector<Entry> entries_;  // linear search: a few entries
  uint64_t clock_ = 0;
};

/// "keyframe: keypoint 12 outside the image" -> "keyframe: keypoint # outside the image".
std::string ReasonKind(const std::string& reason);

// ---- Agent -> server. `cameras` may be null (a model is built per message then).

/// Features beyond kMaxKeypoints are left out, with the links to them. `agent_reference_kf`:
/// the agent's current reference keyframe (Invalid: none).
msg::KeyframeFull ToMsg(const KeyframeData& kf, KeyframeId agent_reference_kf);
std::optional<KeyframeData> FromMsg(const msg::KeyframeFull& m, CameraCache* cameras, std::string* error,
                                    KeyframeId* agent_reference_kf = nullptr);

/// Points and point updates travel in batches of one agent and segment (the batch header
/// carries version, agent and segment; a segment that does not fit, or belongs to another
/// agent, is sent as 0, which every receiver rejects). Empty batches, to fill with ToMsg's.
msg::MapPointBatch PointBatch(AgentId agent, MapId segment);
msg::MapPointUpdateBatch PointUpdateBatch(AgentId agent, MapId segment);
/// A received batch's segment after checking its header (version, segment): nullopt and
/// the reason otherwise. Its elements are then converted with the batch's agent and segment.
std::optional<MapId> BatchSegment(const msg::MapPointBatch& m, std::string* error);
std::optional<MapId> BatchSegment(const msg::MapPointUpdateBatch& m, std::string* error);

/// Observations beyond kMaxObservations are left out. Normal and depth range: zero (the
/// value type does not carry them). mp.segment goes in the batch header (PointBatch).
msg::MapPointFull ToMsg(const MapPointData& mp);
std::optional<MapPointData> FromMsg(const msg::MapPointFull& m, AgentId agent, MapId segment, std::string* error);

/// The segment travels as its 32-bit counter; a segment that does not fit (or belongs to
/// another agent) is sent as 0, which every receiver rejects.
msg::KeyframeUpdate ToMsg(const KeyframePoseUpdate& u);
std::optional<KeyframePoseUpdate> FromMsg(const msg::KeyframeUpdate& m, std::string* error);

/// The segment (the value type has none; the server finds the map through it,
/// AgentBatch::segment) goes in the batch header (PointUpdateBatch).
msg::MapPointUpdate ToMsg(const MapPointPositionUpdate& u);
std::optional<MapPointPositionUpdate> FromMsg(const msg::MapPointUpdate& m, AgentId agent, std::string* error);

// ---- Agent heartbeat.

/// An agent's heartbeat (AgentStatus), validated: only counters and ids to display and log.
struct AgentStatusData {
  AgentId agent = 0;
  int64_t stamp_ns = 0;
  KeyframeId reference_kf;  ///< Invalid: none yet
  MapId segment;            ///< Invalid: none yet
  uint32_t kfs_created = 0, kfs_sent = 0, kfs_acked = 0, kfs_resent = 0, kfs_lost = 0, mps_sent = 0;
  uint32_t write_failures = 0;
  int tracking_state = 0;  ///< 0 not initialized, 1 ok, 2 lost, 3 relocalized
  ServerHoldings holdings;  ///< the server keyframes it holds (downlink deltas)
};

/// Rejects another protocol version, agent 0, a reference keyframe or segment of another
/// agent (0 meaning none) and an unknown tracking state.
std::optional<AgentStatusData> FromMsg(const msg::AgentStatus& m, std::string* error);

// ---- Server -> agent.

/// Where a server message stands in the server's life (idl ServerToAgent, docs/protocol.md
/// "Epochs and persisted acks"): the server's start, this ack message's number in it (0: no
/// acks), and the newest number whose acks are all in the saved map file.
struct ServerAckStamp {
  uint64_t epoch = 1;
  uint64_t ack_seq = 0;
  uint64_t persisted_seq = 0;
};

/// What one ServerToAgent carries, validated.
struct ServerMessage {
  int64_t stamp_ns = 0;
  ServerAckStamp ack_stamp;
  std::vector<KeyframeId> acked_kfs;
  std::vector<MapPointId> acked_mps;
  /// Absent when the message has neither keyframes nor points (acks only).
  std::optional<ServerMapData> data;
};

/// Acks beyond kMaxAcks, keyframes beyond kMaxKeyframesPerServerMsg (or with more than
/// kMaxKeypoints features), points beyond kMaxMapPointsPerServerMsg, observations beyond
/// kMaxObservations, and observations of keyframes left out or of keypoint indices that do
/// not fit the wire are all left out; the rest is sent. `data` may be null (acks only).
msg::ServerToAgent ToMsg(AgentId agent, int64_t stamp_ns, const std::vector<KeyframeId>& acked_kfs,
                         const std::vector<MapPointId>& acked_mps, const ServerMapData* data,
                         const ServerAckStamp& ack_stamp = {});
/// Rejects messages for another agent, epoch 0, acks of ids that are not `expected_agent`'s, and any
/// malformed keyframe or point (the whole message: it is never acked and the next one follows).
std::optional<ServerMessage> FromMsg(const msg::ServerToAgent& m, AgentId expected_agent, CameraCache* cameras,
                                     std::string* error);

}  // namespace ccm::conv
