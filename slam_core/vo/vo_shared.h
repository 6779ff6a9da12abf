// State shared by the agent's tracking and local-mapping components: camera, options,
// the current map segment, id generators and the change log the comm module drains.
// Created and owned by AgentVo; the members say which thread may touch them.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

#include "slam_core/map/map.h"
#include "slam_core/map_ops/change_log.h"
#include "slam_core/vo/relocalization_index.h"
#include "slam_core/vo/vo_options.h"

namespace ccm {

/// Thread-safe ascending ids of one agent (tracking creates keyframes, mapping points).
template <typename IdT>
class AtomicIdGenerator {
 public:
  AtomicIdGenerator(AgentId agent, uint64_t first) : agent_(agent), next_(first == 0 ? 1 : first) {}
  IdT Next() { return IdT::Make(agent_, next_.fetch_add(1)); }

 private:
  const AgentId agent_;
  std::atomic<uint64_t> next_;
};

/// Keyframes of other agents the server sent last (its k most covisible with the agent's
/// reference keyframe, CCM-SLAM 4.5). Tracking adds them to its local map, so their points
/// are matched where the agent's own map has none yet (entering an area another agent
/// mapped). Written by the mapping thread when it applies server data, read by tracking.
class SharedNeighbourhood {
 public:
  void Set(std::vector<KeyframeId> ids) {
    std::lock_guard<std::mutex> lock(mutex_);
    ids_ = std::move(ids);
  }
  std::vector<KeyframeId> Get() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return ids_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<KeyframeId> ids_;
};

struct VoShared {
  VoShared(AgentId agent_id, std::shared_ptr<const CameraModel> cam, const VoOptions& opts)
      : agent(agent_id),
        camera(std::move(cam)),
        options(opts),
        pyramid(std::make_shared<ScalePyramid>(ScalePyramid::Make(opts.orb.num_levels, opts.orb.scale_factor))),
        kf_ids(agent_id, opts.first_id_counter),
        mp_ids(agent_id, opts.first_id_counter),
        map_ids(agent_id, opts.first_segment_counter) {}

  const AgentId agent;
  const std::shared_ptr<const CameraModel> camera;
  const VoOptions options;
  const std::shared_ptr<const ScalePyramid> pyramid;
  AtomicIdGenerator<KeyframeId> kf_ids;
  AtomicIdGenerator<MapPointId> mp_ids;
  AtomicIdGenerator<MapId> map_ids;
  ChangeLog changes;
  SharedNeighbourhood neighbourhood;
  /// Bag-of-words index of the local map (null without a vocabulary: brute-force
  /// relocalization). Synced by the mapping thread, queried by tracking.
  std::unique_ptr<RelocalizationIndex> relocalization;
};

}  // namespace ccm
