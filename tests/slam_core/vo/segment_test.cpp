// When the camera is carried somewhere the local map never saw (here: from the hall3 hall
// into the disjoint2 rooms), relocalization fails and the agent must keep going on a new
// map segment instead of stopping.
#include <gtest/gtest.h>

#include "tests/slam_core/vo/vo_sim_run.h"

namespace ccm {
namespace {

TEST(VoSegments, LostInAnUnknownPlaceStartsANewSegmentAndTracksAgain) {
  std::string error;
  const auto hall = testing::LoadSimulation("hall3", &error);
  ASSERT_NE(hall, nullptr) << error;
  const auto rooms = testing::LoadSimulation("disjoint2", &error);
  ASSERT_NE(rooms, nullptr) << error;
  sim::SimFrameSource first(hall, 0, 0, 1, 120);
  sim::SimFrameSource second(rooms, 1, 0, 1, 200);
  std::shared_ptr<const CameraModel> camera(MakeCamera(first.intrinsics()));
  AckAll acks;
  AgentVo vo(1, camera, VoOptions{}, &acks, /*synchronous_mapping=*/true);
  MapId first_segment;
  while (auto f = first.Next()) first_segment = vo.TrackFrame(*f).segment;
  ASSERT_TRUE(first_segment.valid());
  bool new_segment_reported = false;
  int lost = 0, tracked_in_new_segment = 0;
  MapId last_segment;
  while (auto f = second.Next()) {
    const TrackingResult r = vo.TrackFrame(*f);
    new_segment_reported |= r.new_segment;
    lost += r.state == TrackingState::kLost;
    if (r.world_from_cam && r.segment.valid() && r.segment != first_segment) ++tracked_in_new_segment;
    last_segment = r.segment;
  }
  EXPECT_GT(lost, 0) << "the jump should lose tracking";
  EXPECT_TRUE(new_segment_reported);
  EXPECT_EQ(vo.stats().segments, 2);
  EXPECT_NE(last_segment, first_segment);
  EXPECT_GT(tracked_in_new_segment, 100) << "the agent flies on in the new segment";
}

}  // namespace
}  // namespace ccm
