// Facade of the agent's visual odometry for the runtime: feed frames, read the pose,
// drain changed keyframes/points for the comm module. Tracking and local mapping are
// synchronous steps; the caller decides where they run:
//   * synchronous mapping (tests, deterministic runs): TrackFrame() also processes every
//     new keyframe before returning;
//   * threaded (ccm_agent): the tracking thread calls TrackFrame(), a mapping thread owned
//     by the runtime loops on RunMappingOnce(); Stop() wakes it for shutdown.
// Lock order: jobs_mutex_ is never held while the map or a keyframe is locked;
// lock order mapper_mutex_ -> map_mutex_ (ProcessJob checks the segment while applying server
// data); stats_mutex_ is a leaf (taken under mapper_mutex_ when the mapper's stats are
// published; stats() takes it alone, so it never waits behind a local BA).
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <vector>

#include "slam_core/feature/frame.h"
#include "slam_core/vo/local_mapper.h"
#include "slam_core/vo/tracker.h"

namespace ccm {

struct KeyframePose {
  KeyframeId id;
  MapId segment;
  int64_t stamp_ns = 0;
  SE3 world_from_cam;
};

/// Road-like failed initializations (AgentVoStats::road_like_init_attempts) after which the
/// road profile would have initialized sooner: the agent then points to it (KITTI at 10 Hz:
/// ~2 s; rooms and halls initialize before).
constexpr int64_t kRoadProfileHintAttempts = 20;

struct AgentVoStats {
  int64_t frames = 0;
  int64_t frames_tracked = 0;
  int64_t keyframes_created = 0;
  KeyframeReasonCounts keyframe_reasons{};  ///< why each keyframe was made
  int segments = 0;
  int64_t road_like_init_attempts = 0;  ///< failed initializations on planar or distant views (road ahead?)
  int64_t relocalizations = 0;       ///< lost -> tracking again in the same segment
  int64_t weak_poses = 0;            ///< tracked frames kept from making a keyframe (Tracker::weak_poses)
  size_t relocalization_index_size = 0;  ///< keyframes in the bag-of-words index
  size_t keyframes_in_map = 0;
  size_t map_points_in_map = 0;
  MappingStats mapping;
  TrimStats trim;
  ServerDataStats server;
  /// Timing samples, at most kMaxTimingSamples each (then the oldest are overwritten, so
  /// memory stays bounded on long flights): per frame (feature extraction included) and
  /// per keyframe.
  static constexpr size_t kMaxTimingSamples = 20000;
  std::vector<double> tracking_ms;
  std::vector<double> mapping_ms;
};

/// What changed since the last TakeChanges(): the comm module's input.
struct VoChanges {
  std::shared_ptr<Map> map;  ///< segment the ids refer to
  std::set<KeyframeId> keyframes;
  std::set<MapPointId> map_points;
  KeyframeId reference_kf;
};

class AgentVo {
 public:
  /// With a vocabulary, a lost agent relocalizes through a bag-of-words index of its local
  /// map; without, by matching against every local map point (slower, fails more often in
  /// large maps).
  AgentVo(AgentId agent, std::shared_ptr<const CameraModel> camera, VoOptions options, const AckSource* acks,
          bool synchronous_mapping, std::shared_ptr<const Vocabulary> vocabulary = nullptr);

  /// Tracking thread. Returns the tracking outcome of this frame.
  TrackingResult TrackFrame(const Frame& frame);

  /// Mapping thread: waits up to `timeout` for a keyframe and processes it. False if
  /// none arrived or Stop() was called.
  bool RunMappingOnce(std::chrono::milliseconds timeout);
  void Stop();
  /// Processes queued keyframes on the calling thread (end of a threaded run).
  void DrainMapping();
  bool mapping_idle() const;
  /// Blocks until the mapping thread has processed every queued job (or Stop()). Offline
  /// "as fast as possible" runs use it so tracking never outruns mapping.
  void WaitUntilMappingIdle();

  /// Any thread (the comm module): queues server data for the mapping thread; returns
  /// at once. Data for a segment that has since been replaced is dropped.
  void ApplyServerData(ServerMapData data);

  VoChanges TakeChanges();
  /// Keyframes + points changed and not taken yet (bounded by the local map's size: ids
  /// that left the map are pruned from time to time).
  size_t pending_changes() const { return shared_.changes.size(); }
  std::shared_ptr<Map> map() const;
  AgentVoStats stats() const;
  /// Any thread: the server keyframes in the current segment's local map after the newest
  /// mapping job, and the stamp of the newest server data processed (the comm module reports
  /// both to the server, which then sends those keyframes as poses only).
  ServerHoldings Holdings() const;
  /// Per tracked frame: its pose composed with the final pose of its reference keyframe
  /// (as ORB-SLAM writes trajectories, so later keyframe refinement improves every frame).
  /// Frames whose keyframe vanished with a discarded segment keep their tracking pose.
  /// Recorded only with VoOptions::record_frame_trajectory.
  std::vector<KeyframePose> FrameTrajectory() const;
  /// Poses of all keyframes ever created: retired ones with their last pose, then the
  /// current segment's map. Sorted by id.
  std::vector<KeyframePose> KeyframeTrajectory() const;

 private:
  /// One unit of work for the mapping thread: a new keyframe or server data.
  struct MappingJob {
    std::optional<KeyframeJob> keyframe;
    std::shared_ptr<Map> map;  ///< for server data: the segment it belongs to
    std::optional<ServerMapData> server;
  };
  void Enqueue(MappingJob job);
  void ProcessJob(const MappingJob& job);
  /// Mapping thread, holding mapper_mutex_; `applied`: the server data just processed.
  void PublishMapperStats(const ServerMapData* applied = nullptr);
  /// Mapping thread: the relocalization index follows the current segment's keyframes.
  void SyncRelocalizationIndex();

  VoShared shared_;
  const bool synchronous_;
  OrbExtractor extractor_, init_extractor_;
  Tracker tracker_;
  mutable std::mutex mapper_mutex_;  // guards mapper_ (its stats are read by other threads)
  LocalMapper mapper_;
  int64_t frame_index_ = 0;

  mutable std::mutex jobs_mutex_;
  std::condition_variable jobs_cv_;
  std::condition_variable idle_cv_;
  std::deque<MappingJob> jobs_;
  bool stopping_ = false;
  bool mapping_busy_ = false;

  struct FrameRecord {
    int64_t stamp_ns;
    KeyframeId reference;
    SE3 reference_from_cam;
    SE3 world_from_cam;  ///< at tracking time (fallback)
  };
  std::vector<FrameRecord> frame_records_;  // tracking thread only

  std::shared_ptr<Map> CurrentMap() const;
  // The tracker's segment as published after each frame, for other threads (the tracker
  // itself may swap its map when it re-initializes).
  mutable std::mutex map_mutex_;
  std::shared_ptr<Map> current_map_;
  KeyframeId current_ref_;

  mutable std::mutex stats_mutex_;
  AgentVoStats stats_;
  int64_t mapping_samples_ = 0;  // guarded by stats_mutex_
  ServerHoldings holdings_;      // guarded by stats_mutex_
};

}  // namespace ccm
