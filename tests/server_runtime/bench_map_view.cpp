// bench_map_view (issue 14): the map view's API latency over a real socket at N keyframes,
// the snapshot's refresh time and longest back-end lock hold, and the update traffic of a
// page polling at 2 Hz while the map grows (steady state), at two map sizes to show it stays
// flat. Prints numbers; docs/map-view.md has them. Not a test: no asserts on timing.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <thread>
#include <cstdio>

#include "server_runtime/map_view_api.h"
#include "server_runtime/map_view_server.h"
#include "tests/server_runtime/map_view_fixture.h"

// After every Eigen header: httplib.h brings <resolv.h>, whose `_res` macro breaks Eigen's
// templates parsed after it.
#include <httplib.h>

namespace {

using Clock = std::chrono::steady_clock;

struct Sample {
  double ms = 0;
  size_t bytes = 0;
};

Sample Fetch(httplib::Client& client, const std::string& path, bool gzip) {
  httplib::Headers headers;
  if (gzip) headers.emplace("Accept-Encoding", "gzip");
  const auto t0 = Clock::now();
  const auto r = client.Get(path.c_str(), headers);
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (!r || r->status != 200) {
    std::fprintf(stderr, "GET %s failed\n", path.c_str());
    std::exit(1);
  }
  return {ms, r->body.size()};
}

void PrintLatency(httplib::Client& client, const std::string& path, int repeats) {
  std::vector<double> ms;
  size_t raw = 0, gz = 0;
  for (int i = 0; i < repeats; ++i) {
    const Sample s = Fetch(client, path, false);
    ms.push_back(s.ms);
    raw = s.bytes;
  }
  gz = Fetch(client, path, true).bytes;
  std::sort(ms.begin(), ms.end());
  std::printf("  GET %-28s median %7.2f ms  max %7.2f ms  %9zu B (%zu B gzip)\n", path.c_str(), ms[ms.size() / 2],
              ms.back(), raw, gz);
}

/// Grows the map by one keyframe per agent and moves each agent's last 10 keyframes (as a
/// local BA would) per poll; a page polls status + map delta + events.
void SteadyState(ccm::testing::ViewBackend* b, ccm::server::MapViewServer* view, httplib::Client& client, int agents,
                 int points_per_kf, int polls, double* x) {
  uint64_t version = 0;
  size_t events = 0;
  {
    const auto j = nlohmann::json::parse(client.Get("/api/map?since=0")->body);
    version = j["version"].get<uint64_t>();
  }
  double ms = 0, max_ms = 0;
  size_t raw = 0, gz = 0;
  for (int p = 0; p < polls; ++p) {
    *x += 0.1;
    for (int a = 1; a <= agents; ++a) {
      const ccm::KeyframeId newest = b->AddKeyframe(static_cast<ccm::AgentId>(a), *x, points_per_kf);
      for (uint64_t c = newest.counter() > 10 ? newest.counter() - 10 : 1; c < newest.counter(); ++c) {
        auto kf = b->MapOf(static_cast<ccm::AgentId>(a))->map().keyframe(ccm::KeyframeId::Make(a, c));
        if (!kf) continue;
        ccm::SE3 pose = kf->world_from_cam();
        kf->SetWorldFromCam(ccm::SE3(pose.rotation(), pose.translation() + Eigen::Vector3d(0, 0.01, 0)));
      }
    }
    view->RefreshNow();
    for (const bool gzip : {false, true}) {
      const std::string map_path = "/api/map?since=" + std::to_string(version);
      const Sample s1 = Fetch(client, "/api/status", gzip), s2 = Fetch(client, map_path, gzip),
                   s3 = Fetch(client, "/api/events?since=" + std::to_string(events), gzip);
      (gzip ? gz : raw) += s1.bytes + s2.bytes + s3.bytes;
      if (!gzip) {
        ms += s1.ms + s2.ms + s3.ms;
        max_ms = std::max({max_ms, s1.ms, s2.ms, s3.ms});
      }
    }
    version = nlohmann::json::parse(client.Get("/api/map?since=0")->body)["version"].get<uint64_t>();
  }
  std::printf("  steady state (%d new KFs + %d moved KFs + %d new points per poll): %.1f kB/poll = %.1f kB/s at 2 Hz "
              "(gzip %.1f kB/s); %.2f ms per poll (3 requests), max request %.2f ms\n",
              agents, agents * 10, agents * points_per_kf, raw / 1024.0 / polls, 2 * raw / 1024.0 / polls,
              2 * gz / 1024.0 / polls, ms / polls, max_ms);
}

/// What the SLAM threads feel: the latency of a map write (AddMapPoint takes the Map's
/// table lock exclusively) while the view refreshes back to back, against none refreshing.
void WriterLatency(ccm::testing::ViewBackend* b, ccm::server::MapViewServer* view) {
  auto map = b->MapOf(1);
  uint64_t next = 1ull << 40;  // ids far from the fixture's
  for (const int mode : {0, 1, 2}) {  // idle, 2 Hz (the view's rate), back to back
    std::atomic<bool> done{false};
    std::thread refresher([&] {
      while (mode > 0 && !done) {
        view->RefreshNow();
        for (int i = 0; mode == 1 && i < 50 && !done; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
    });
    std::vector<double> us;
    const auto until = Clock::now() + std::chrono::seconds(2);
    while (Clock::now() < until) {
      auto mp = std::make_shared<ccm::MapPoint>(ccm::MapPointId::Make(1, next++), Eigen::Vector3d(0, 0, 5),
                                                ccm::KeyframeId::Make(1, 1), ccm::OrbDescriptor{});
      const auto t0 = Clock::now();
      map->map().AddMapPoint(mp);
      us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
      map->map().EraseMapPoint(mp->id());
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    done = true;
    refresher.join();
    std::sort(us.begin(), us.end());
    static const char* kMode[] = {"view idle", "view refreshing at 2 Hz", "view refreshing back to back"};
    std::printf("  map write (AddMapPoint), %-28s: median %.1f us, p99 %.0f us, max %.0f us (%zu writes)\n", kMode[mode],
                us[us.size() / 2], us[us.size() * 99 / 100], us.back(), us.size());
  }
}

/// The API's own time (no socket) for the full map and a status.
void ApiComputeTime(const ccm::ServerBackend& backend) {
  ccm::server::MapViewModel model(&backend, ccm::server::MapViewOptions{});
  model.Refresh();
  const auto snap = model.Latest();
  std::vector<double> ms;
  size_t bytes = 0;
  for (int i = 0; i < 10; ++i) {
    const auto t0 = Clock::now();
    bytes = ccm::server::HandleApiRequest(*snap, "/api/map", {{"since", "0"}}).body.size();
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  std::printf("  /api/map?since=0 computed without the socket: median %.2f ms (%zu B)\n", ms[5], bytes);
}

}  // namespace

int main(int argc, char** argv) {
  int keyframes = 2000, agents = 2, points_per_kf = 60, polls = 20, repeats = 20;
  CLI::App app{"bench_map_view: map view API latency and update traffic"};
  app.add_option("--keyframes", keyframes, "keyframes in the map at the end")->capture_default_str();
  app.add_option("--agents", agents, "agents (one map each)")->capture_default_str();
  app.add_option("--points-per-kf", points_per_kf, "new map points per keyframe")->capture_default_str();
  app.add_option("--polls", polls, "polls in each steady-state run")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  ccm::testing::ViewBackend b(2 * points_per_kf + 10);
  ccm::server::MapViewServerOptions o;
  o.port = 0;
  std::string error;
  auto view = ccm::server::MapViewServer::Start(o, &b.backend(), {}, &error);
  if (!view) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  httplib::Client client("127.0.0.1", view->port());
  client.set_decompress(false);
  double x = 0;
  for (const int size : {keyframes / 4, keyframes}) {
    while (x * 10 * agents < size) {
      x += 0.1;
      for (int a = 1; a <= agents; ++a) b.AddKeyframe(static_cast<ccm::AgentId>(a), x, points_per_kf);
    }
    std::vector<double> refresh;
    for (int i = 0; i < 5; ++i) {
      view->RefreshNow();
      refresh.push_back(nlohmann::json::parse(client.Get("/api/status")->body)["snapshot"]["refresh_ms"].get<double>());
    }
    const auto status = nlohmann::json::parse(client.Get("/api/status")->body);
    std::printf("map: %d keyframes, %d map points (%d in the view, stride %d), %d covisibility edges\n",
                status["totals"]["keyframes"].get<int>(), status["totals"]["map_points"].get<int>(),
                status["snapshot"]["points"].get<int>(), status["snapshot"]["point_stride"].get<int>(),
                status["snapshot"]["edges"].get<int>());
    std::sort(refresh.begin(), refresh.end());
    std::printf("  snapshot refresh median %.2f ms, longest back-end lock hold %.0f us (max over all refreshes %.0f us)\n",
                refresh[2], status["snapshot"]["max_lock_hold_us"].get<double>(),
                status["snapshot"]["max_lock_hold_us_ever"].get<double>());
    PrintLatency(client, "/api/status", repeats);
    PrintLatency(client, "/metrics", repeats);
    PrintLatency(client, "/api/map?since=0", repeats);
    PrintLatency(client, "/api/map?since=0&min_weight=50", repeats);
    PrintLatency(client, "/api/events", repeats);
    ApiComputeTime(b.backend());
    SteadyState(&b, view.get(), client, agents, points_per_kf, polls, &x);
  }
  WriterLatency(&b, view.get());
  view->Stop();
  return 0;
}
