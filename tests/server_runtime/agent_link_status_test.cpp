// What the server keeps of an agent's heartbeats (server_runtime/server_comm.h ApplyStatus):
// the counters as sent, and a list of the agent's segments that a hostile agent naming a
// fresh segment id in every heartbeat cannot grow without end.
#include <gtest/gtest.h>

#include "server_runtime/server_comm.h"

namespace ccm::server {
namespace {

constexpr AgentId kStatusAgent = 3;

conv::AgentStatusData Status(uint64_t segment_counter) {
  conv::AgentStatusData st;
  st.agent = kStatusAgent;
  st.reference_kf = KeyframeId::Make(kStatusAgent, 7);
  st.segment = MapId::Make(kStatusAgent, segment_counter);
  st.kfs_created = 9;
  st.kfs_sent = 8;
  st.kfs_acked = 6;
  st.tracking_state = 2;
  return st;
}

TEST(AgentLinkStatus, AHeartbeatSetsTheCountersAndTheCurrentSegment) {
  AgentLink link;
  ApplyStatus(Status(1), &link);
  EXPECT_EQ(link.status_msgs, 1);
  EXPECT_EQ(link.reference_kf, KeyframeId::Make(kStatusAgent, 7));
  EXPECT_EQ(link.segment, MapId::Make(kStatusAgent, 1));
  EXPECT_EQ(link.kfs_created, 9u);
  EXPECT_EQ(link.kfs_acked, 6u);
  EXPECT_EQ(link.tracking_state, 2);
  EXPECT_EQ(link.segments.size(), 1u);
}

TEST(AgentLinkStatus, FreshSegmentsInEveryHeartbeatListAtMostTheCapAndTheRestIsCounted) {
  AgentLink link;
  constexpr uint64_t kHeartbeats = 10000;
  for (uint64_t i = 1; i <= kHeartbeats; ++i) ApplyStatus(Status(i), &link);
  EXPECT_EQ(link.segments.size(), kMaxSegmentsListed);
  EXPECT_EQ(link.segments_not_listed, static_cast<int64_t>(kHeartbeats - kMaxSegmentsListed));
  EXPECT_EQ(link.segment, MapId::Make(kStatusAgent, kHeartbeats)) << "the current segment is still the newest";
  ApplyStatus(Status(1), &link);  // a listed one again: not counted as unlisted
  EXPECT_EQ(link.segments_not_listed, static_cast<int64_t>(kHeartbeats - kMaxSegmentsListed));
}

}  // namespace
}  // namespace ccm::server
