// The operators' live map view (issue 14): an embedded HTTP server (cpp-httplib) that
// serves the page in server_runtime/web/, three.js from Debian's libjs-three and the JSON
// API of map_view_api.h. Used by ccm_server and ccm_replay (`--http PORT`).
// It owns two things that run: the HTTP server (its accept loop on one thread, requests on
// a small pool owned by httplib::Server) and the snapshot thread, which refreshes the
// MapViewModel at refresh_hz while a client asked in the last few seconds (no client: no
// cost). Handlers only read the latest immutable snapshot, so the SLAM threads never wait
// on HTTP and the HTTP threads never wait on SLAM. Start() binds or fails with a message;
// Stop() (or the destructor) joins both. Bound to 127.0.0.1 unless --http-bind says more.
#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "server_runtime/map_view_snapshot.h"

namespace CLI {
class App;
}
namespace httplib {
class Server;
}

namespace ccm::server {

struct MapViewServerOptions {
  int port = -1;                      ///< -1: off; 0: any free port (printed)
  std::string bind = "127.0.0.1";     ///< 0.0.0.0 opens it to the ground network
  std::string web_root;               ///< the page (index.html, app.js, style.css); "" = built-in path
  std::string three_dir = "/usr/share/javascript/three";  ///< Debian's libjs-three
  double refresh_hz = 2.0;            ///< snapshots per second while a client is active
  size_t threads = 4;                 ///< HTTP request threads
  MapViewOptions model;
  bool enabled() const { return port >= 0; }
  std::string Validate() const;
};

/// Adds --http, --http-bind, --http-root, --http-three, --http-max-points to a command line
/// (ccm_server and ccm_replay share them).
void AddMapViewOptions(CLI::App* app, MapViewServerOptions* options);

class MapViewServer {
 public:
  /// Binds and starts serving; nullptr and *error if the port, the page or three.js is not there.
  static std::unique_ptr<MapViewServer> Start(const MapViewServerOptions& options, const ServerBackend* backend,
                                              HostStatusFn host_status, std::string* error);
  ~MapViewServer();
  MapViewServer(const MapViewServer&) = delete;
  MapViewServer& operator=(const MapViewServer&) = delete;

  /// Stops serving and joins every thread. Idempotent.
  void Stop();
  int port() const { return port_; }
  std::string url() const;
  /// Refreshes the snapshot now (tests, the end of a replay).
  void RefreshNow() { model_.Refresh(); }

 private:
  MapViewServer(const MapViewServerOptions& options, const ServerBackend* backend, HostStatusFn host_status);
  bool Setup(std::string* error);
  void SnapshotLoop();
  void NoteRequest();
  nlohmann::json HttpCounters() const;

  const MapViewServerOptions options_;
  MapViewModel model_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = -1;

  std::atomic<int64_t> requests_{0}, api_requests_{0}, api_bytes_{0}, static_bytes_{0}, errors_{0}, metrics_requests_{0};
  std::mutex mutex_;  // guards last_request_, refreshes_, stopping_; leaf
  std::condition_variable cv_;
  std::chrono::steady_clock::time_point last_request_{};
  int64_t refreshes_ = 0;
  bool stopping_ = false;
  std::thread http_thread_, snapshot_thread_;
};

}  // namespace ccm::server
