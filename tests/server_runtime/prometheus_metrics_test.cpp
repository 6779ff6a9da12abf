// GET /metrics (issue 32): the renderer on a hand-made status, and the HTTP route against
// /api/status of the same server. tests/server_runtime/metrics_scrape_test.py parses a live
// scrape with Prometheus' own parser.
#include "server_runtime/prometheus_metrics.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <set>
#include <sstream>

#include "server_runtime/map_view_server.h"
#include "tests/server_runtime/map_view_fixture.h"

namespace ccm::server {
namespace {

using json = nlohmann::json;

int CountLines(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  int n = 0;
  for (std::string line; std::getline(in, line);) n += line.rfind(prefix, 0) == 0 ? 1 : 0;
  return n;
}

TEST(PrometheusMetrics, EveryFamilyOnceWithItsSamplesTogetherAndLabelsEscaped) {
  const json status = {
      {"totals", {{"agents", 2}, {"maps", 1}, {"keyframes", 40}, {"fusions", 1}, {"global_ba_seconds", 2.5}}},
      {"queues", {{"place_recognition", 3}, {"global_ba_running", true}}},
      {"agents",
       {{{"id", 1}, {"name", "cam \"left\"\\1\nx"}, {"queue", 2}, {"lag_s", 0.75}, {"registered", 17},
         {"tracking", "lost"}, {"alive", true}},
        {{"id", 2}, {"queue", 0}, {"registered", 23}}}},
      {"host", {{"elapsed_s", 61.5}, {"traffic", {{{"topic", "ccm/keyframes"}, {"direction", "in"}, {"bytes", 4096}}}}}}};
  const std::string text = ServerMetricsText(status);
  EXPECT_NE(text.find("ccm_server_keyframes 40\n"), std::string::npos) << text;
  EXPECT_NE(text.find("ccm_server_global_ba_seconds_total 2.5\n"), std::string::npos);
  EXPECT_NE(text.find("ccm_server_global_ba_running 1\n"), std::string::npos);
  EXPECT_NE(text.find("ccm_server_agent_queue_batches{agent=\"1\",name=\"cam \\\"left\\\"\\\\1\\nx\"} 2\n"),
            std::string::npos);
  EXPECT_NE(text.find("ccm_server_agent_registration_lag_seconds{agent=\"1\","), std::string::npos);
  EXPECT_NE(text.find("ccm_server_agent_keyframes_registered_total{agent=\"2\"} 23\n"), std::string::npos);
  EXPECT_NE(text.find("ccm_server_agent_tracking_state{agent=\"1\",name=\"cam \\\"left\\\"\\\\1\\nx\",state=\"lost\"} 1"),
            std::string::npos);
  EXPECT_EQ(CountLines(text, "ccm_server_agent_tracking_state{agent=\"1\""), 4) << "one-hot over the states";
  EXPECT_NE(text.find("ccm_server_dds_payload_bytes_total{topic=\"ccm/keyframes\",direction=\"in\"} 4096\n"),
            std::string::npos);
  EXPECT_NE(text.find("ccm_server_uptime_seconds 61.5\n"), std::string::npos);
  // Absent facts are absent, not 0: no autosave, no loop count, agent 2 has no lag field.
  EXPECT_EQ(text.find("autosave"), std::string::npos);
  EXPECT_EQ(text.find("ccm_server_loops_total"), std::string::npos);
  EXPECT_EQ(CountLines(text, "ccm_server_agent_registration_lag_seconds{"), 1);
  // One HELP and one TYPE per family, right before its samples, which are together.
  std::istringstream in(text);
  std::string family, line;
  std::set<std::string> seen;
  while (std::getline(in, line)) {
    ASSERT_FALSE(line.empty());
    if (line.rfind("# HELP ", 0) == 0) {
      family = line.substr(7, line.find(' ', 7) - 7);
      EXPECT_TRUE(seen.insert(family).second) << family << " described twice";
      ASSERT_TRUE(std::getline(in, line));
      EXPECT_EQ(line.rfind("# TYPE " + family + " ", 0), 0u) << line;
      continue;
    }
    EXPECT_EQ(line.rfind(family, 0), 0u) << line << " outside its family " << family;
  }
  EXPECT_GT(seen.size(), 12u);
}

TEST(MapViewServer, MetricsAgreeWithTheStatusAndNeedNoViewClient) {
  testing::ViewBackend b;
  b.AddKeyframe(1, 0, 5);
  b.AddKeyframe(1, 1, 5);
  b.AddKeyframe(2, 0, 5);
  MapViewServerOptions o;
  o.port = 0;
  std::string error;
  auto server = MapViewServer::Start(o, &b.backend(), [] { return json{{"source", "test"}, {"autosave_age_s", 12.5}}; },
                                     &error);
  ASSERT_TRUE(server) << error;
  httplib::Client client("127.0.0.1", server->port());
  b.AddKeyframe(2, 1, 5);  // after the view's first snapshot: a scrape must see it anyway
  auto r = client.Get("/metrics");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), kPrometheusContentType);
  EXPECT_NE(r->body.find("ccm_server_keyframes 4\n"), std::string::npos) << r->body;
  EXPECT_NE(r->body.find("ccm_server_agent_keyframes{agent=\"2\"} 2\n"), std::string::npos);
  EXPECT_NE(r->body.find("ccm_server_autosave_age_seconds 12.5\n"), std::string::npos);
  EXPECT_NE(r->body.find("ccm_server_metrics_scrapes_total 1\n"), std::string::npos);
  server->RefreshNow();
  auto s = client.Get("/api/status");
  ASSERT_TRUE(s);
  const json status = json::parse(s->body);
  EXPECT_NE(r->body.find("ccm_server_maps " + std::to_string(status["totals"]["maps"].get<int>()) + "\n"),
            std::string::npos);
  EXPECT_NE(r->body.find("ccm_server_map_points " + std::to_string(status["totals"]["map_points"].get<int>()) + "\n"),
            std::string::npos);
  r = client.Post("/metrics", "x", "text/plain");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
  server->Stop();
}

}  // namespace
}  // namespace ccm::server
