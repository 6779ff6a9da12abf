// ccm_agent --metrics (issue 32): the text from the tracking gauges and the comm counters, and
// the endpoint's life (bind, serve, refuse a port in use, stop). The live scrape against a
// server is tests/system/metrics_live_test.py.
#include "agent_runtime/agent_metrics.h"

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace ccm::agent {
namespace {

// A GET over a plain socket (the test needs no HTTP library of its own).
std::string HttpGet(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    close(fd);
    return "";
  }
  const std::string request = "GET " + path + " HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n";
  (void)!write(fd, request.data(), request.size());
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = read(fd, buf, sizeof(buf))) > 0;) out.append(buf, static_cast<size_t>(n));
  close(fd);
  return out;
}

TEST(AgentMetrics, TextCarriesTheGaugesAndTheLinkCounters) {
  FlightGauges g;
  g.frames = 120;
  g.tracked = 117;
  g.frames_skipped = 4;
  g.keyframes_created = 21;
  g.segments = 2;
  g.state = 2;  // lost
  const std::string standalone = AgentMetricsText(7, g, nullptr);
  EXPECT_NE(standalone.find("ccm_agent_frames_total{agent=\"7\"} 120\n"), std::string::npos) << standalone;
  EXPECT_NE(standalone.find("ccm_agent_frames_tracked_total{agent=\"7\"} 117\n"), std::string::npos);
  EXPECT_NE(standalone.find("ccm_agent_frames_skipped_total{agent=\"7\"} 4\n"), std::string::npos);
  EXPECT_NE(standalone.find("ccm_agent_tracking_state{agent=\"7\",state=\"lost\"} 1\n"), std::string::npos);
  EXPECT_NE(standalone.find("ccm_agent_tracking_state{agent=\"7\",state=\"tracking\"} 0\n"), std::string::npos);
  EXPECT_NE(standalone.find("ccm_agent_segments{agent=\"7\"} 2\n"), std::string::npos);
  EXPECT_EQ(standalone.find("keyframes_sent"), std::string::npos) << "no link families without a link";
  AgentCommStats c;
  c.kfs_sent = 19;
  c.kfs_acked = 17;
  c.kfs_unacked = 2;
  c.backlog_bytes = 40960;
  const std::string linked = AgentMetricsText(7, g, &c);
  EXPECT_NE(linked.find("# TYPE ccm_agent_keyframes_sent_total counter\nccm_agent_keyframes_sent_total{agent=\"7\"} 19\n"),
            std::string::npos) << linked;
  EXPECT_NE(linked.find("ccm_agent_keyframes_unacked{agent=\"7\"} 2\n"), std::string::npos);
  EXPECT_NE(linked.find("ccm_agent_backlog_bytes{agent=\"7\"} 40960\n"), std::string::npos);
}

TEST(AgentMetrics, EndpointServesMetricsOnlyAndRefusesAPortInUse) {
  int renders = 0;
  std::string error;
  auto endpoint = MetricsEndpoint::Start("127.0.0.1", 0, [&renders] {
    ++renders;
    return std::string("ccm_agent_frames_total{agent=\"1\"} 5\n");
  }, &error);
#ifdef CCM_AGENT_HTTP
  ASSERT_TRUE(endpoint) << error;
  ASSERT_GT(endpoint->port(), 0);
  const std::string ok = HttpGet(endpoint->port(), "/metrics");
  EXPECT_NE(ok.find("200 OK"), std::string::npos) << ok;
  EXPECT_NE(ok.find("text/plain; version=0.0.4"), std::string::npos) << ok;
  EXPECT_NE(ok.find("ccm_agent_frames_total{agent=\"1\"} 5"), std::string::npos);
  EXPECT_NE(HttpGet(endpoint->port(), "/").find("404"), std::string::npos);
  EXPECT_EQ(renders, 1);
  EXPECT_FALSE(MetricsEndpoint::Start("127.0.0.1", endpoint->port(), [] { return std::string(); }, &error));
  EXPECT_NE(error.find("cannot listen"), std::string::npos) << error;
  const int port = endpoint->port();
  endpoint->Stop();
  EXPECT_EQ(HttpGet(port, "/metrics"), "") << "closed";
#else
  EXPECT_FALSE(endpoint);
  EXPECT_NE(error.find("without cpp-httplib"), std::string::npos) << error;
#endif
}

}  // namespace
}  // namespace ccm::agent
