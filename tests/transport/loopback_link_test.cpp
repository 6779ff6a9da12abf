// Two-process loopback links under injected faults (20% datagram loss, 100 ms delay in
// both processes, wifi.xml: 1400 B datagrams). RELIABLE new data must arrive completely,
// exactly once and bit-exact; BEST_EFFORT updates arrive partially and the loss is counted.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/transport/subprocess.h"

namespace ccm {
namespace {

struct LinkRun {
  nlohmann::json pub, sub;
  std::string pub_log, sub_log;
};

nlohmann::json LastJsonLine(const std::string& output) {
  const auto start = output.rfind("\n{");
  const std::string line = output.substr(start == std::string::npos ? 0 : start + 1);
  return nlohmann::json::parse(line, nullptr, false);
}

LinkRun RunLink(const std::string& kind, int count, double rate_hz, int domain) {
  const std::string qos = std::string(CCM_QOS_DIR) + "/wifi.xml";
  const std::vector<std::string> common = {"--kind", kind, "--count", std::to_string(count), "--rate",
                                           std::to_string(rate_hz), "--qos", qos, "--domain", std::to_string(domain),
                                           "--drop", "0.2", "--delay-ms", "100", "--timeout", "90"};
  std::vector<std::string> sub = {CCM_LINK_PROBE, "--role", "sub", "--idle", "20"};
  std::vector<std::string> pub = {CCM_LINK_PROBE, "--role", "pub"};
  sub.insert(sub.end(), common.begin(), common.end());
  pub.insert(pub.end(), common.begin(), common.end());
  const auto results = testing::RunConcurrently({sub, pub}, ::testing::TempDir() + "/link_" + kind,
                                                std::chrono::seconds(150));
  LinkRun run;
  run.sub_log = results[0].output;
  run.pub_log = results[1].output;
  EXPECT_EQ(results[0].exit_code, 0) << run.sub_log;
  EXPECT_EQ(results[1].exit_code, 0) << run.pub_log;
  run.sub = LastJsonLine(run.sub_log);
  run.pub = LastJsonLine(run.pub_log);
  return run;
}

TEST(LoopbackLink, ReliableKeyframesSurviveLossAndDelayExactlyOnce) {
  const LinkRun run = RunLink("keyframes", 200, 10.0, 161);
  ASSERT_TRUE(run.sub.is_object()) << run.sub_log;
  ASSERT_TRUE(run.pub.is_object()) << run.pub_log;
  EXPECT_EQ(run.pub["published"], 200);
  EXPECT_EQ(run.pub["write_failures"], 0);
  EXPECT_EQ(run.sub["received_unique"], 200) << run.sub_log;
  EXPECT_EQ(run.sub["duplicates"], 0);
  EXPECT_EQ(run.sub["mismatches"], 0);
  EXPECT_EQ(run.sub["missing_count"], 0);
  // The faults were real: both processes dropped about 20% of what reached them.
  // (The subscriber receives data fragments, the publisher ACKNACKs and discovery.)
  for (const auto* side : {&run.sub, &run.pub}) {
    const double received = (*side)["wire"]["datagrams_received"];
    const double dropped = (*side)["wire"]["datagrams_dropped"];
    ASSERT_GT(received, 300.0);
    EXPECT_NEAR(dropped / received, 0.2, 0.06);
  }
  // 200 keyframes of ~55 kB in 1400 B fragments: far more than 200 datagrams crossed.
  EXPECT_GT(run.sub["wire"]["datagrams_received"].get<double>(), 200.0 * 40);
}

TEST(LoopbackLink, BestEffortUpdatesArrivePartiallyAndLossIsCounted) {
  const LinkRun run = RunLink("updates", 400, 50.0, 162);
  ASSERT_TRUE(run.sub.is_object()) << run.sub_log;
  const int received = run.sub["received_unique"];
  const int missing = run.sub["missing_count"];
  EXPECT_EQ(run.sub["duplicates"], 0);
  EXPECT_EQ(run.sub["mismatches"], 0);
  EXPECT_EQ(received + missing, 400);
  // The publisher starts when its writer has matched the reader; the reader may match the
  // writer later (its discovery datagrams are dropped too) and BEST_EFFORT data before that
  // is gone. So the wire's loss is measured from the first update that arrived on; matching
  // must still happen early in the 8 s stream (under CI load it took up to ~3.6 s).
  const int first = run.sub["first_index"];
  ASSERT_GE(first, 0) << run.sub_log;
  EXPECT_LT(first, 300) << run.sub_log;
  const double window = 400 - first;
  // 20% datagram loss on one hop: roughly 80% arrive (generous bounds).
  EXPECT_GT(received, window * 0.6) << run.sub_log;
  EXPECT_LT(received, window * 0.95) << run.sub_log;
  // The reader itself noticed the gaps (Fast DDS sample-lost status).
  EXPECT_GT(run.sub["reader_samples_lost"].get<int>(), 0) << run.sub_log;
}

}  // namespace
}  // namespace ccm
