#include "server_runtime/map_view_server.h"


#include <CLI/CLI.hpp>
#include <filesystem>

#include "server_runtime/map_view_api.h"
#include "server_runtime/prometheus_metrics.h"

// After every Eigen header: httplib.h brings <resolv.h>, whose `_res` macro breaks Eigen's
// templates parsed after it.
#include <httplib.h>

#include "slam_core/common/install_paths.h"

#ifndef CCM_MAP_VIEW_WEB_ROOT
#define CCM_MAP_VIEW_WEB_ROOT ""
#endif

namespace ccm::server {
namespace {

using Clock = std::chrono::steady_clock;
/// A client that asked within this long keeps the snapshot thread refreshing.
constexpr std::chrono::seconds kClientActive(5);

void SetJson(httplib::Response& res, const ApiResponse& a) {
  res.status = a.status;
  res.set_content(a.body, a.content_type.c_str());
  res.set_header("Cache-Control", "no-store");
}

}  // namespace

std::string MapViewServerOptions::Validate() const {
  if (port < -1 || port > 65535) return "--http port must be in 0..65535";
  if (bind.empty()) return "--http-bind must name an address (127.0.0.1, 0.0.0.0, ...)";
  if (!(refresh_hz > 0.0 && refresh_hz <= 50.0)) return "map view refresh rate must be in (0, 50] Hz";
  if (threads < 1 || threads > 64) return "map view threads must be in 1..64";
  return model.Validate();
}

void AddMapViewOptions(CLI::App* app, MapViewServerOptions* o) {
  app->add_option("--http", o->port, "serve the live map view on this port (0: any free port; docs/map-view.md)");
  app->add_option("--http-bind", o->bind, "address the map view listens on (0.0.0.0: the whole network)")
      ->capture_default_str();
  app->add_option("--http-root", o->web_root, "folder of the map view page (default: the one built in)");
  app->add_option("--http-three", o->three_dir, "folder of three.js r111 (Debian libjs-three)")->capture_default_str();
  app->add_option("--http-max-points", o->model.max_points, "map points the view shows at most (decimated)")
      ->capture_default_str();
}

MapViewServer::MapViewServer(const MapViewServerOptions& options, const ServerBackend* backend,
                             HostStatusFn host_status)
    : options_(options), model_(backend, options.model, std::move(host_status)) {}

std::unique_ptr<MapViewServer> MapViewServer::Start(const MapViewServerOptions& options, const ServerBackend* backend,
                                                    HostStatusFn host_status, std::string* error) {
  if (const std::string problem = options.Validate(); !problem.empty()) {
    *error = problem;
    return nullptr;
  }
  std::unique_ptr<MapViewServer> server(new MapViewServer(options, backend, std::move(host_status)));
  if (!server->Setup(error)) return nullptr;
  return server;
}

bool MapViewServer::Setup(std::string* error) {
  namespace fs = std::filesystem;
  // Default: the installed page beside the binary (packages), else the source tree's.
  const std::string root =
      options_.web_root.empty() ? rt::FindDataFile("web", CCM_MAP_VIEW_WEB_ROOT) : options_.web_root;
  if (root.empty() || !fs::exists(fs::path(root) / "index.html")) {
    *error = "map view page not found: no index.html in '" + root + "' (give --http-root DIR)";
    return false;
  }
  if (!fs::exists(fs::path(options_.three_dir) / "build/three.min.js") ||
      !fs::exists(fs::path(options_.three_dir) / "examples/js/controls/OrbitControls.js")) {
    *error = "three.js not found in '" + options_.three_dir + "' (apt-get install libjs-three, or give --http-three DIR)";
    return false;
  }
  http_ = std::make_unique<httplib::Server>();
  const size_t threads = options_.threads;
  http_->new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  http_->set_payload_max_length(64 * 1024);  // the API takes no request bodies
  // httplib's default adds SO_REUSEPORT, which lets a second server bind the same port
  // silently; keep SO_REUSEADDR only, so a port in use is an error.
  http_->set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  http_->set_mount_point("/", root);
  http_->set_mount_point("/three", options_.three_dir);
  http_->Get(R"(/api/.*)", [this](const httplib::Request& req, httplib::Response& res) {
    NoteRequest();
    ++api_requests_;
    QueryParams params;
    for (const auto& [name, value] : req.params) {
      if (!params.emplace(name, value).second) {
        SetJson(res, ApiError(400, "parameter '" + name.substr(0, 40) + "' given more than once"));
        return;
      }
    }
    SetJson(res, HandleApiRequest(*model_.Latest(), req.path, params, HttpCounters()));
  });
  // Prometheus scrapes (docs/monitoring.md): a status taken now, not the view's snapshot.
  http_->Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    ++metrics_requests_;
    nlohmann::json status = model_.CurrentStatus();
    status["http"] = HttpCounters()["http"];
    res.set_content(ServerMetricsText(status), kPrometheusContentType);
    res.set_header("Cache-Control", "no-store");
  });
  // Read-only API: any other method is refused with a clear 405.
  const auto refuse = [](const httplib::Request& req, httplib::Response& res) {
    SetJson(res, ApiError(405, "method " + req.method + " not allowed: the map view is read-only (GET)"));
  };
  http_->Post(".*", refuse);
  http_->Put(".*", refuse);
  http_->Delete(".*", refuse);
  http_->Patch(".*", refuse);
  http_->set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    const std::string what = res.status == 404 ? "not found: '" + req.path.substr(0, 100) + "'"
                                               : "bad request (" + std::to_string(res.status) + ")";
    SetJson(res, ApiError(res.status, what));
  });
  http_->set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what += std::string(": ") + e.what();
    } catch (...) {
    }
    SetJson(res, ApiError(500, what));
  });
  http_->set_logger([this](const httplib::Request& req, const httplib::Response& res) {
    ++requests_;
    if (res.status >= 400) ++errors_;
    (req.path.rfind("/api/", 0) == 0 ? api_bytes_ : static_bytes_) += static_cast<int64_t>(res.body.size());
  });
  port_ = options_.port == 0 ? http_->bind_to_any_port(options_.bind) : options_.port;
  if (port_ < 0 || (options_.port != 0 && !http_->bind_to_port(options_.bind, options_.port))) {
    *error = "map view: cannot listen on " + options_.bind + ":" + std::to_string(options_.port) +
             " (address in use or not local?)";
    return false;
  }
  model_.Refresh();  // the first page load has data at once
  http_thread_ = std::thread([this] { http_->listen_after_bind(); });
  snapshot_thread_ = std::thread([this] { SnapshotLoop(); });
  // httplib 0.11 has no "ready" signal, and a stop() before its accept loop runs is lost
  // (Stop would then wait forever): wait, bounded, until it runs.
  for (int i = 0; i < 2000 && !http_->is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return true;
}

MapViewServer::~MapViewServer() { Stop(); }

void MapViewServer::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  cv_.notify_all();
  if (http_) http_->stop();
  if (http_thread_.joinable()) http_thread_.join();
  if (snapshot_thread_.joinable()) snapshot_thread_.join();
}

std::string MapViewServer::url() const {
  const std::string host = options_.bind == "0.0.0.0" ? "127.0.0.1" : options_.bind;
  return "http://" + host + ":" + std::to_string(port_) + "/";
}

void MapViewServer::NoteRequest() {
  std::unique_lock<std::mutex> lock(mutex_);
  const bool was_idle = Clock::now() - last_request_ > kClientActive;
  last_request_ = Clock::now();
  if (!was_idle) return;  // the loop is refreshing: the snapshot is at most one period old
  // The snapshot thread slept: wake it and wait (bounded) for a fresh snapshot, so the first
  // answer after a pause is not an old picture. This waits on the view's own thread only.
  const int64_t seen = refreshes_;
  cv_.notify_all();
  cv_.wait_for(lock, std::chrono::seconds(1), [&] { return refreshes_ != seen || stopping_; });
}

void MapViewServer::SnapshotLoop() {
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / options_.refresh_hz));
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_) {
    const bool active = Clock::now() - last_request_ <= kClientActive;
    if (active) {
      lock.unlock();
      model_.Refresh();
      lock.lock();
      ++refreshes_;
      cv_.notify_all();  // NoteRequest may wait for this one
      cv_.wait_for(lock, period, [this] { return stopping_; });
    } else {
      // Idle: no refresh until a request comes in (NoteRequest wakes us).
      cv_.wait(lock, [this] { return stopping_ || Clock::now() - last_request_ <= kClientActive; });
    }
  }
}

nlohmann::json MapViewServer::HttpCounters() const {
  return {{"http",
           {{"requests", requests_.load()},
            {"api_requests", api_requests_.load()},
            {"api_bytes", api_bytes_.load()},
            {"static_bytes", static_bytes_.load()},
            {"errors", errors_.load()},
            {"metrics_requests", metrics_requests_.load()},
            {"refresh_hz", options_.refresh_hz}}}};
}

}  // namespace ccm::server
