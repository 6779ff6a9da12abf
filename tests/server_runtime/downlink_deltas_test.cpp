// DownlinkDeltas: what the server sends an agent as poses / positions only, from what the
// agent reports holding and what was sent since the server message it had integrated.
#include <gtest/gtest.h>

#include "server_runtime/downlink_deltas.h"

namespace ccm::server {
namespace {

const KeyframeId kA = KeyframeId::Make(2, 1), kB = KeyframeId::Make(2, 2), kC = KeyframeId::Make(3, 1);
const MapPointId kP = MapPointId::Make(2, 10), kQ = MapPointId::Make(2, 11), kR = MapPointId::Make(3, 12);

ServerKeyframe Kf(KeyframeId id, const std::unordered_set<KeyframeId>& held) {
  ServerKeyframe k;
  k.id = id;
  k.held = held.count(id) > 0;
  return k;
}

ServerMapPoint Point(MapPointId id, std::vector<KeyframeId> seen_by) {
  ServerMapPoint p;
  p.id = id;
  for (const KeyframeId k : seen_by) p.observations.emplace_back(k, 0);
  p.observations.emplace_back(KeyframeId::Make(1, 5), 0);  // the agent's own keyframe
  return p;
}

// A neighbourhood of kA, kB, kC with points kP (seen by kA), kQ (kB) and kR (kC), marked
// for `deltas` as ServerComm does.
ServerMapData Neighbourhood(const DownlinkDeltas& deltas) {
  const auto held = deltas.HeldKeyframes();
  ServerMapData d;
  d.keyframes = {Kf(kA, held), Kf(kB, held), Kf(kC, held)};
  d.map_points = {Point(kP, {kA}), Point(kQ, {kB}), Point(kR, {kC})};
  deltas.MarkHeldPoints(&d);
  return d;
}

TEST(DownlinkDeltas, AnAgentThatNeverReportsIntegratingGetsEverythingInFull) {
  DownlinkDeltas deltas;
  deltas.OnHoldings({0, {kA}});  // a recording: nothing integrated, whatever it lists
  for (int i = 0; i < 3; ++i) {
    const ServerMapData d = Neighbourhood(deltas);
    for (const auto& k : d.keyframes) EXPECT_FALSE(k.held);
    for (const auto& p : d.map_points) EXPECT_FALSE(p.held);
    deltas.RecordSent(1000 + i, d);
  }
}

TEST(DownlinkDeltas, WhatTheAgentHoldsAndWhatIsInFlightGoCheapUntilItIsReportedGone) {
  DownlinkDeltas deltas;
  deltas.OnHoldings({100, {kA}});
  ServerMapData d1 = Neighbourhood(deltas);
  EXPECT_TRUE(d1.keyframes[0].held);
  EXPECT_FALSE(d1.keyframes[1].held);
  EXPECT_FALSE(d1.keyframes[2].held);
  for (const auto& p : d1.map_points) EXPECT_FALSE(p.held) << "no point was sent in full before";
  deltas.RecordSent(200, d1);  // kB, kC and all three points go in full

  // Before the agent reports integrating message 200, kB and kC count as held (in flight).
  ServerMapData d2 = Neighbourhood(deltas);
  for (const auto& k : d2.keyframes) EXPECT_TRUE(k.held);
  for (const auto& p : d2.map_points) EXPECT_TRUE(p.held);
  deltas.RecordSent(300, d2);

  // The agent integrated message 200 and then dropped kB: kB goes in full again, with kQ.
  deltas.OnHoldings({200, {kA, kC}});
  ServerMapData d3 = Neighbourhood(deltas);
  EXPECT_TRUE(d3.keyframes[0].held);
  EXPECT_FALSE(d3.keyframes[1].held);
  EXPECT_TRUE(d3.keyframes[2].held);
  EXPECT_TRUE(d3.map_points[0].held);
  EXPECT_FALSE(d3.map_points[1].held) << "seen by a keyframe going in full: the agent may have dropped it";
  EXPECT_TRUE(d3.map_points[2].held);
}

TEST(DownlinkDeltas, AFullSendTheAgentNeverReportsExpires) {
  DownlinkDeltas deltas;
  deltas.OnHoldings({100, {}});
  const ServerMapData d1 = Neighbourhood(deltas);
  deltas.RecordSent(200, d1);
  EXPECT_EQ(deltas.HeldKeyframes().size(), 3u) << "in flight";
  // Lost on the way: the agent keeps reporting message 100. Later sends push it out.
  ServerMapData later;
  deltas.RecordSent(200 + DownlinkDeltas::kInFlightNs + 1, later);
  EXPECT_TRUE(deltas.HeldKeyframes().empty());
}

TEST(DownlinkDeltas, APointOutOfEveryNeighbourhoodForAMinuteIsForgottenAndGoesInFullAgain) {
  DownlinkDeltas deltas;
  deltas.OnHoldings({100, {kA, kB, kC}});
  int64_t t = 200;
  ServerMapData first;
  first.map_points = {Point(kP, {kA}), Point(kQ, {kB})};
  deltas.MarkHeldPoints(&first);
  deltas.RecordSent(t, first);
  EXPECT_EQ(deltas.points_remembered(), 2u);
  // kP stays in the neighbourhoods (as a position), kQ leaves them.
  const int64_t step = 5'000'000'000;
  for (; t < 200 + DownlinkDeltas::kForgetPointNs + 3 * step; t += step) {
    ServerMapData d;
    d.map_points = {Point(kP, {kA})};
    deltas.MarkHeldPoints(&d);
    EXPECT_TRUE(d.map_points[0].held);
    deltas.RecordSent(t, d);
  }
  EXPECT_EQ(deltas.points_remembered(), 1u) << "kQ was forgotten, kP kept";
  ServerMapData back;
  back.map_points = {Point(kP, {kA}), Point(kQ, {kB})};
  deltas.MarkHeldPoints(&back);
  EXPECT_TRUE(back.map_points[0].held);
  EXPECT_FALSE(back.map_points[1].held) << "a forgotten point goes in full";
}

}  // namespace
}  // namespace ccm::server
