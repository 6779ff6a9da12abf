#include "slam_core/server/detection_stage.h"

#include <string>
#include <utility>

#include "slam_core/server/loop_closer.h"
#include "slam_core/server/map_fuser.h"

namespace ccm {

DetectionStage::DetectionStage(MapStack* stack, const ServerOptions& options, Hooks hooks)
    : stack_(stack), options_(options), hooks_(std::move(hooks)) {}

DetectionOutcome DetectionStage::Handle(const PlaceDetection& d, double time_s) const {
  ServerEvent e;
  e.time_s = time_s;
  e.agent = d.query.agent();
  e.query = d.query;
  e.candidate = d.candidate;
  e.query_from_candidate = d.query_from_candidate;
  if (const auto m = stack_->MapHolding(d.query)) {
    if (const auto kf = m->map().keyframe(d.query)) e.stamp_ns = kf->stamp_ns();
  }
  DetectionOutcome out = d.kind == PlaceDetection::Kind::kLoop ? CloseLoopOf(d, std::move(e)) : FuseMapsOf(d, std::move(e));
  if (out.event) {
    if (const auto m = stack_->GetMap(out.event->map)) out.event->keyframes = static_cast<int>(m->map().num_keyframes());
  }
  return out;
}

DetectionOutcome DetectionStage::CloseLoopOf(const PlaceDetection& d, ServerEvent e) const {
  DetectionOutcome out;
  const LoopReport r = CloseLoop(stack_, d, options_);
  if (!r.closed) {
    out.refused = r.reason;
    return out;
  }
  if (hooks_.loop_closed) hooks_.loop_closed(r.map);
  e.kind = ServerEvent::Kind::kLoop;
  e.map = r.map;
  e.seconds = r.seconds;
  e.detail = "moved " + std::to_string(r.correction_m) + " m / " + std::to_string(r.correction_deg) + " deg, scale x" +
             std::to_string(r.scale_correction) + ", " + std::to_string(r.points_fused) + " points fused, " +
             std::to_string(r.loop_connections) + " loop connections, pose graph " + std::to_string(r.pose_graph_s) +
             " s unlocked, map locked " + std::to_string(r.locked_s) + " s";
  if (options_.optimization.global_ba_after_loop) out.optimize = r.map;
  out.event = std::move(e);
  return out;
}

DetectionOutcome DetectionStage::FuseMapsOf(const PlaceDetection& d, ServerEvent e) const {
  DetectionOutcome out;
  const FusionReport r = FuseMaps(stack_, d, options_.mapping.overlap_weld_depth_ratio, [this](MapId absorbed, MapId kept) {
    if (hooks_.maps_fused) hooks_.maps_fused(absorbed, kept);
  });
  if (!r.fused) {
    out.refused = r.reason;
    return out;
  }
  e.kind = ServerEvent::Kind::kFusion;
  e.map = r.kept;
  e.other_map = r.absorbed;
  e.seconds = r.seconds;
  e.detail = "scale " + std::to_string(r.kept_from_absorbed.scale()) + ", " + std::to_string(r.keyframes_moved) +
             " keyframes moved, " + std::to_string(r.points_merged) + " points merged, overlap " +
             (r.refined ? "refined on " : "not refined, ") + std::to_string(r.overlap_inliers) + "/" +
             std::to_string(r.overlap_pairs) + " point pairs";
  if (options_.mapping.overlap_weld_depth_ratio > 0.0) {
    e.detail += ", welded " + std::to_string(r.weld_merged) + " on " + std::to_string(r.weld_targets) + " keyframes";
  }
  out.forget = r.absorbed;
  if (options_.optimization.global_ba_after_fusion) out.optimize = r.kept;
  out.event = std::move(e);
  return out;
}

}  // namespace ccm
