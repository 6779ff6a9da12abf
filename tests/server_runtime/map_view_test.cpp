// The map view (issue 14): snapshots, versioned deltas, decimation, API errors, and the
// HTTP server over a real socket. The page in headless Chromium is map_view_page_test.py.
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "server_runtime/map_view_api.h"
#include "server_runtime/map_view_server.h"
#include "server_runtime/server_outputs.h"
#include "tests/server_runtime/map_view_fixture.h"

// After every Eigen header: httplib.h brings <resolv.h>, whose `_res` macro breaks Eigen's
// templates parsed after it.
#include <httplib.h>

namespace ccm::server {
namespace {

using nlohmann::json;

json Get(const MapViewModel& model, const std::string& path, const QueryParams& params, int* status = nullptr) {
  const ApiResponse r = HandleApiRequest(*model.Latest(), path, params);
  if (status) *status = r.status;
  return json::parse(r.body);
}

/// What a client holds after applying deltas: id -> element (as the API sends it).
struct Mirror {
  std::map<std::string, json> keyframes, points, edges;
  uint64_t version = 0;
  void Apply(const json& m) {
    if (m["reset"].get<bool>()) keyframes.clear(), points.clear(), edges.clear();
    for (const auto& id : m["removed"]["keyframes"]) keyframes.erase(id.get<std::string>());
    for (const auto& id : m["removed"]["points"]) points.erase(id.get<std::string>());
    for (const auto& e : m["removed"]["edges"]) edges.erase(e[0].get<std::string>() + "|" + e[1].get<std::string>());
    for (const auto& k : m["keyframes"]) keyframes[k[0].get<std::string>()] = k;
    for (const auto& p : m["points"]) points[p[0].get<std::string>()] = p;
    for (const auto& e : m["edges"]) edges[e[0].get<std::string>() + "|" + e[1].get<std::string>()] = e;
    version = m["version"].get<uint64_t>();
  }
};

TEST(MapView, DeltasCarryOnlyWhatChangedAndReplayToTheFullMap) {
  testing::ViewBackend b;
  MapViewModel model(&b.backend(), MapViewOptions{});
  model.Refresh();
  EXPECT_EQ(model.Latest()->version, 0u);  // nothing there yet
  for (int i = 0; i < 5; ++i) b.AddKeyframe(1, i, 30);
  model.Refresh();
  const uint64_t v1 = model.Latest()->version;
  EXPECT_EQ(v1, 1u);
  Mirror client;
  client.Apply(Get(model, "/api/map", {{"since", "0"}}));
  EXPECT_EQ(client.keyframes.size(), 5u);
  EXPECT_EQ(client.points.size(), 150u);
  EXPECT_EQ(client.edges.size(), 4u);  // consecutive keyframes share 30 points each

  model.Refresh();  // nothing changed: same version, empty delta
  EXPECT_EQ(model.Latest()->version, v1);
  json d = Get(model, "/api/map", {{"since", std::to_string(v1)}});
  EXPECT_TRUE(d["keyframes"].empty() && d["points"].empty() && d["edges"].empty());
  EXPECT_FALSE(d["reset"].get<bool>());

  // One keyframe moves, one is added, one point goes: the delta has exactly those.
  const auto map = b.MapOf(1);
  const KeyframeId moved = KeyframeId::Make(1, 2), gone_kf = KeyframeId::Make(1, 5);
  map->map().keyframe(moved)->SetWorldFromCam(SE3(Eigen::Quaterniond::Identity(), {1.0, 0.3, 0}));
  const MapPointId gone_point = MapPointId::Make(1, 1);
  ASSERT_TRUE(map->map().EraseMapPoint(gone_point));
  b.AddKeyframe(1, 5, 30);
  ASSERT_TRUE(map->map().EraseKeyframe(gone_kf));
  model.Refresh();
  d = Get(model, "/api/map", {{"since", std::to_string(v1)}});
  std::set<std::string> changed;
  for (const auto& k : d["keyframes"]) changed.insert(k[0].get<std::string>());
  EXPECT_EQ(changed, (std::set<std::string>{"1:2", "1:6"}));
  EXPECT_EQ(d["removed"]["keyframes"], json::array({"1:5"}));
  EXPECT_NE(std::find(d["removed"]["points"].begin(), d["removed"]["points"].end(), "1:1"), d["removed"]["points"].end());
  EXPECT_NEAR(d["keyframes"][0][3].get<double>(), 0.3, 1e-6);  // y of 1:2 (sorted first)
  client.Apply(d);

  Mirror full;
  full.Apply(Get(model, "/api/map", {{"since", "0"}}));
  EXPECT_EQ(client.keyframes, full.keyframes);
  EXPECT_EQ(client.points, full.points);
  EXPECT_EQ(client.edges, full.edges);
  EXPECT_EQ(client.version, full.version);
}

// A fusion adds the absorbed map's keyframes and points to the kept map and only then drops
// the absorbed map: a snapshot taken in between sees them in both. A client following the
// deltas across that moment must still end with every one of them.
TEST(MapView, ElementsInTwoMapsDuringAFusionAreNotLostByClients) {
  testing::ViewBackend b;
  MapViewModel model(&b.backend(), MapViewOptions{});
  for (int i = 0; i < 4; ++i) b.AddKeyframe(1, i, 20);
  b.AddKeyframe(2, 10, 20);
  model.Refresh();
  Mirror client;
  client.Apply(Get(model, "/api/map", {{"since", "0"}}));
  ASSERT_EQ(client.points.size(), 100u);

  auto absorbed = b.MapOf(1), kept = b.MapOf(2);
  for (const auto& kf : absorbed->map().keyframes()) kept->map().AddKeyframe(kf);
  for (const auto& mp : absorbed->map().map_points()) kept->map().AddMapPoint(mp);
  model.Refresh();  // both maps list agent 1's elements
  client.Apply(Get(model, "/api/map", {{"since", std::to_string(client.version)}}));
  b.map_stack().Repoint(absorbed->id(), kept->id(), Sim3());
  model.Refresh();  // the absorbed map is gone
  client.Apply(Get(model, "/api/map", {{"since", std::to_string(client.version)}}));

  Mirror full;
  full.Apply(Get(model, "/api/map", {{"since", "0"}}));
  EXPECT_EQ(full.keyframes.size(), 5u);
  EXPECT_EQ(full.points.size(), 100u);
  EXPECT_EQ(client.keyframes, full.keyframes);
  EXPECT_EQ(client.points, full.points);
  EXPECT_EQ(client.edges, full.edges);
  const std::string kept_id = IdText(kept->id().packed());
  for (const auto& [id, k] : client.keyframes) EXPECT_EQ(k[1].get<std::string>(), kept_id) << id;
}

TEST(MapView, SlowDriftGoesOutOnceItAddsUp) {
  testing::ViewBackend b;
  MapViewModel model(&b.backend(), MapViewOptions{});  // min_change_m 2 mm
  b.AddKeyframe(1, 0, 5);
  model.Refresh();
  Mirror client;
  client.Apply(Get(model, "/api/map", {{"since", "0"}}));
  auto kf = b.MapOf(1)->map().keyframe(KeyframeId::Make(1, 1));
  std::vector<size_t> sent;
  for (int step = 1; step <= 6; ++step) {  // 0.9 mm per refresh
    kf->SetWorldFromCam(SE3(Eigen::Quaterniond::Identity(), {0.0009 * step, 0, 0}));
    model.Refresh();
    const json d = Get(model, "/api/map", {{"since", std::to_string(client.version)}});
    sent.push_back(d["keyframes"].size());
    client.Apply(d);
    Mirror full;
    full.Apply(Get(model, "/api/map", {{"since", "0"}}));
    EXPECT_EQ(client.keyframes, full.keyframes) << "step " << step;  // the snapshot keeps what was sent
  }
  EXPECT_EQ(sent, (std::vector<size_t>{0, 0, 1, 0, 0, 1}));  // at 2.7 mm and 5.4 mm
  EXPECT_NEAR(client.keyframes["1:1"][2].get<double>(), 0.0054, 0.0006);  // sent in mm
}

TEST(MapView, MinWeightDropsWeakEdgesAndOldClientsReloadInFull) {
  testing::ViewBackend b;
  MapViewOptions o;
  o.tombstone_versions = 2;
  MapViewModel model(&b.backend(), o);
  b.AddKeyframe(1, 0, 10);
  b.AddKeyframe(1, 1, 40);  // edge 1:1-1:2 weight 40
  b.AddKeyframe(1, 2, 20);  // edge 1:2-1:3 weight 20
  model.Refresh();
  json d = Get(model, "/api/map", {{"since", "0"}, {"min_weight", "30"}});
  ASSERT_EQ(d["edges"].size(), 1u);
  EXPECT_EQ(d["edges"][0][2].get<int>(), 40);
  for (int i = 3; i < 7; ++i) {  // versions 2..5, each with a removal
    b.AddKeyframe(1, i, 20);
    ASSERT_TRUE(b.MapOf(1)->map().EraseMapPoint(MapPointId::Make(1, i)));
    model.Refresh();
  }
  EXPECT_EQ(model.Latest()->version, 5u);
  EXPECT_TRUE(Get(model, "/api/map", {{"since", "1"}})["reset"].get<bool>());  // its removals are forgotten
  EXPECT_FALSE(Get(model, "/api/map", {{"since", "4"}})["reset"].get<bool>());
}

TEST(MapView, DecimatesLargeMapsStably) {
  testing::ViewBackend b(400);
  MapViewOptions o;
  o.max_points = 100;
  MapViewModel model(&b.backend(), o);
  for (int i = 0; i < 10; ++i) b.AddKeyframe(1, i, 100);  // 1000 points
  model.Refresh();
  const auto s = model.Latest();
  EXPECT_EQ(s->point_stride, 16u);  // 1000 / 8 > 100, 1000 / 16 <= 100
  EXPECT_LE(s->points.size(), 100u);
  EXPECT_GT(s->points.size(), 20u);
  EXPECT_EQ(Get(model, "/api/status", {})["totals"]["map_points"].get<int>(), 1000);
  model.Refresh();
  EXPECT_EQ(model.Latest()->version, s->version);  // the same subset: no change
}

TEST(MapView, StatusCountsAgentsMapsEventsAndHostFacts) {
  testing::ViewBackend b;
  MapViewModel model(&b.backend(), MapViewOptions{}, [] {
    return json{{"agents", {{"2", {{"tracking", "lost"}}}, {"7", {{"name", "spare"}}}}}, {"source", "test"}};
  });
  b.AddKeyframe(1, 0, 5);
  b.AddKeyframe(2, 0, 5);
  b.AddKeyframe(2, 1, 5);
  model.Refresh();
  const json s = Get(model, "/api/status", {});
  EXPECT_EQ(s["totals"]["agents"].get<int>(), 3);  // 1 and 2 registered, 7 known to the host
  EXPECT_EQ(s["totals"]["maps"].get<int>(), 2);
  EXPECT_EQ(s["totals"]["keyframes"].get<int>(), 3);
  EXPECT_EQ(s["agents"][1]["id"].get<int>(), 2);
  EXPECT_EQ(s["agents"][1]["tracking"], "lost");
  EXPECT_EQ(s["agents"][1]["last_keyframe"], "2:2");
  EXPECT_NEAR(s["agents"][1]["pose"][0].get<double>(), 1.0, 1e-9);
  EXPECT_EQ(s["host"]["source"], "test");
  EXPECT_GE(s["snapshot"]["max_lock_hold_us"].get<double>(), 0.0);
  EXPECT_EQ(s["snapshot"]["refreshes"].get<int>(), 1);
  const json e = Get(model, "/api/events", {});
  EXPECT_EQ(e["total"].get<int>(), 0);
}

TEST(MapView, BadRequestsGetClearErrors) {
  testing::ViewBackend b;
  MapViewModel model(&b.backend(), MapViewOptions{});
  b.AddKeyframe(1, 0, 5);
  model.Refresh();
  const std::vector<std::pair<std::string, QueryParams>> bad = {
      {"/api/map", {{"since", "abc"}}},        {"/api/map", {{"since", "-1"}}},
      {"/api/map", {{"since", "2"}}},          {"/api/map", {{"since", "99999999999999999999999"}}},
      {"/api/map", {{"min_weight", "1e9"}}},   {"/api/map", {{"min_weight", "2000000"}}},
      {"/api/map", {{"bogus", "1"}}},          {"/api/events", {{"since", "5"}}},
      {"/api/events", {{"limit", "0"}}},       {"/api/events", {{"limit", "100000"}}},
      {"/api/status", {{"x", ""}}}};
  for (const auto& [path, params] : bad) {
    int status = 0;
    const json j = Get(model, path, params, &status);
    EXPECT_EQ(status, 400) << path << " " << params.begin()->first;
    EXPECT_FALSE(j["error"].get<std::string>().empty());
  }
  int status = 0;
  EXPECT_NE(Get(model, "/api/nope", {}, &status)["error"].get<std::string>().find("/api/nope"), std::string::npos);
  EXPECT_EQ(status, 404);
}

TEST(MapViewServer, ServesTheApiAndThePageOverHttp) {
  testing::ViewBackend b;
  b.AddKeyframe(1, 0, 5);
  MapViewServerOptions o;
  o.port = 0;
  std::string error;
  auto server = MapViewServer::Start(o, &b.backend(), {}, &error);
  ASSERT_TRUE(server) << error;
  ASSERT_GT(server->port(), 0);
  httplib::Client client("127.0.0.1", server->port());
  auto r = client.Get("/api/status");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(json::parse(r->body)["totals"]["keyframes"].get<int>(), 1);
  r = client.Get("/");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_NE(r->body.find("view-status"), std::string::npos);
  r = client.Get("/three/build/three.min.js");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  r = client.Get("/missing.html");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
  EXPECT_TRUE(json::parse(r->body).contains("error"));
  r = client.Get("/api/map?since=1&since=0");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  r = client.Post("/api/status", "x", "text/plain");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
  server->Stop();
  EXPECT_FALSE(client.Get("/api/status"));  // closed
}

TEST(MapViewServer, StartFailsClearly) {
  testing::ViewBackend b;
  std::string error;
  MapViewServerOptions o;
  o.port = 0;
  o.web_root = "/nonexistent/web";
  EXPECT_FALSE(MapViewServer::Start(o, &b.backend(), {}, &error));
  EXPECT_NE(error.find("/nonexistent/web"), std::string::npos);
  o.web_root.clear();
  o.three_dir = "/nonexistent/three";
  EXPECT_FALSE(MapViewServer::Start(o, &b.backend(), {}, &error));
  EXPECT_NE(error.find("libjs-three"), std::string::npos);
  o.three_dir = MapViewServerOptions{}.three_dir;
  o.port = 70000;
  EXPECT_FALSE(MapViewServer::Start(o, &b.backend(), {}, &error));
  // A port in use.
  o.port = 0;
  auto first = MapViewServer::Start(o, &b.backend(), {}, &error);
  ASSERT_TRUE(first) << error;
  o.port = first->port();
  EXPECT_FALSE(MapViewServer::Start(o, &b.backend(), {}, &error));
  EXPECT_NE(error.find(std::to_string(first->port())), std::string::npos);
}

}  // namespace
}  // namespace ccm::server

namespace ccm::server {
namespace {

// ccm_server's part of the status: each agent's link from its heartbeats, merged per agent.
TEST(MapView, ServerHostStatusShowsLinksAndMergesPerAgent) {
  ServerCommStats comm;
  comm.agents[2].alive = true;
  comm.agents[2].tracking_state = 2;
  comm.agents[2].kfs_sent = 40;
  comm.agents[2].kfs_acked = 38;
  comm.agents[3].tracking_state = 9;  // not a state the agent sends
  rt::TopicCountersSnapshot t;
  t.topic = "ccm/keyframes";
  t.direction = "in";
  t.payload_bytes = 1234;
  const json host = MapViewHostStatus(comm, {t});
  EXPECT_EQ(host["agents"]["2"]["tracking"], "lost");
  EXPECT_EQ(host["agents"]["3"]["tracking"], "unknown");
  EXPECT_EQ(host["traffic"][0]["bytes"].get<int>(), 1234);

  testing::ViewBackend b;
  b.AddKeyframe(2, 0, 5);
  MapViewModel model(&b.backend(), MapViewOptions{}, [&] { return MapViewHostStatus(comm, {t}); });
  model.Refresh();
  const json s = Get(model, "/api/status", {});
  ASSERT_EQ(s["agents"].size(), 2u);  // agent 2 (registered + link), agent 3 (link only)
  EXPECT_EQ(s["agents"][0]["keyframes"].get<int>(), 1);
  EXPECT_EQ(s["agents"][0]["kfs_acked"].get<int>(), 38);
  EXPECT_TRUE(s["agents"][0]["alive"].get<bool>());
  EXPECT_EQ(s["host"]["traffic"][0]["topic"], "ccm/keyframes");
}

}  // namespace
}  // namespace ccm::server
