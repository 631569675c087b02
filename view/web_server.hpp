#pragma once
// The view's web server (civetweb): the page's static files, the events (`/events`, Server-Sent
// Events from an EventHub) and the view's counters (`/metrics`, Prometheus text). It listens on
// one address and port only. Each open page holds one of the server's threads while it reads its
// events; beyond the hub's max_clients a page is answered 503, and a browser that stops reading is
// dropped once a write has waited `write_timeout`.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "common/base/status.hpp"
#include "view/event_hub.hpp"

struct mg_context;
struct mg_connection;

namespace fogmap::view {

// A file of the page, compiled into the binary (view/web/, embedded by the build).
struct WebAsset {
  std::string_view path;  // "/index.html", "/view.js", "/view.css"
  std::string_view content_type;
  std::string_view body;
};
std::span<const WebAsset> webAssets();

struct WebServerOptions {
  std::string address = "127.0.0.1";  // an IPv4 address; the server listens there only
  std::uint16_t port = 8080;          // 0: one the kernel chooses (port() tells)
  std::chrono::milliseconds write_timeout{5000};
  std::function<std::string()> metrics_text;  // the body of /metrics (empty: 404)
};

class WebServer {
 public:
  // Starts listening; an error names the address when it cannot (in use, not local, not IPv4).
  static Expected<std::unique_ptr<WebServer>> start(const WebServerOptions& options, EventHub& hub);
  ~WebServer();  // stops the hub's readers, then the server
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  std::uint16_t port() const { return port_; }
  std::string url() const;  // the page: "http://" then address:port and "/"

 private:
  WebServer(const WebServerOptions& options, EventHub& hub) : options_(options), hub_(hub) {}
  static int serve(mg_connection* connection, void* server);  // every request: by its path
  static int serveAsset(mg_connection* connection, const WebAsset& asset);
  static int serveEvents(mg_connection* connection, void* server);
  static int serveMetrics(mg_connection* connection, void* server);

  WebServerOptions options_;
  EventHub& hub_;
  mg_context* context_ = nullptr;
  std::uint16_t port_ = 0;
};

}  // namespace fogmap::view
