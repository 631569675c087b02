#include "view/web_server.hpp"

#include <arpa/inet.h>

#include <civetweb.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "services/common/http_stop.hpp"


namespace fogmap::view {
namespace {

// Threads for static files and /metrics beside the pages that hold one each while they read events.
constexpr std::size_t kSpareThreads = 4;
// How long a reader waits for an event before it looks again whether the server stops.
constexpr std::chrono::milliseconds kReaderWait{500};
// The page's EventSource reconnects this long after it lost the server (SSE "retry:").
constexpr int kRetryMs = 1000;

bool isGet(mg_connection* connection) {
  const mg_request_info* info = mg_get_request_info(connection);
  return info != nullptr && info->request_method != nullptr && std::strcmp(info->request_method, "GET") == 0;
}

bool writeAll(mg_connection* connection, const std::string& text) {
  return mg_write(connection, text.data(), text.size()) == static_cast<int>(text.size());
}

int notGet(mg_connection* connection) {
  mg_send_http_error(connection, 405, "%s", "only GET is served here\n");
  return 405;
}

}  // namespace

Expected<std::unique_ptr<WebServer>> WebServer::start(const WebServerOptions& options, EventHub& hub) {
  in_addr parsed{};
  if (::inet_pton(AF_INET, options.address.c_str(), &parsed) != 1) {
    return invalidArgument("--listen: '" + options.address + "' is not an IPv4 address");
  }
  std::unique_ptr<WebServer> server(new WebServer(options, hub));
  const std::string ports = options.address + ":" + std::to_string(options.port);
  const std::string threads = std::to_string(hub.maxClients() + kSpareThreads);
  const std::string timeout = std::to_string(options.write_timeout.count());
  const char* civet_options[] = {"listening_ports", ports.c_str(), "num_threads", threads.c_str(), "request_timeout_ms",
                                 timeout.c_str(), "enable_keep_alive", "no", nullptr};
  mg_callbacks callbacks{};
  // civetweb's own complaints (a client that went away, a bad request) are not the view's errors.
  callbacks.log_message = [](const mg_connection*, const char*) { return 1; };
  mg_init_library(0);
  server->context_ = mg_start(&callbacks, nullptr, civet_options);
  if (server->context_ == nullptr) {
    return ioError("cannot listen on " + ports + " (in use, or not an address of this machine?)");
  }
  mg_server_port bound[4]{};
  const int count = mg_get_server_ports(server->context_, 4, bound);
  server->port_ = count > 0 ? static_cast<std::uint16_t>(bound[0].port) : options.port;
  // One handler for every path, which dispatches itself: no reliance on civetweb's order of matching.
  mg_set_request_handler(server->context_, "/", &WebServer::serve, server.get());
  return server;
}

WebServer::~WebServer() {
  hub_.stop();  // the pages' streams end
  if (context_ != nullptr) stopHttpServer([this] { mg_stop(context_); }, options_.address, port_);
}

std::string WebServer::url() const { return "http://" + options_.address + ":" + std::to_string(port_) + "/"; }

int WebServer::serve(mg_connection* connection, void* self) {
  if (!isGet(connection)) return notGet(connection);
  const mg_request_info* info = mg_get_request_info(connection);
  const std::string_view path = info->local_uri != nullptr ? info->local_uri : "";
  if (path == "/events") return serveEvents(connection, self);
  if (path == "/metrics") return serveMetrics(connection, self);
  for (const WebAsset& asset : webAssets()) {
    if (path == asset.path || (path == "/" && asset.path == "/index.html")) return serveAsset(connection, asset);
  }
  mg_send_http_error(connection, 404, "%s", "not found: the view serves /, /events and /metrics\n");
  return 404;
}

int WebServer::serveAsset(mg_connection* connection, const WebAsset& a) {
  mg_printf(connection,
            "HTTP/1.1 200 OK\r\nContent-Type: %.*s\r\nContent-Length: %zu\r\nCache-Control: no-cache\r\n"
            "X-Content-Type-Options: nosniff\r\nConnection: close\r\n\r\n",
            static_cast<int>(a.content_type.size()), a.content_type.data(), a.body.size());
  mg_write(connection, a.body.data(), a.body.size());
  return 200;
}

int WebServer::serveEvents(mg_connection* connection, void* self) {
  auto& server = *static_cast<WebServer*>(self);
  auto reader = server.hub_.join();
  if (!reader) {
    mg_send_http_error(connection, 503, "the view serves %zu pages at once; close one and reload\n", server.hub_.maxClients());
    return 503;
  }
  if (!writeAll(connection, "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-cache\r\n"
                            "Connection: close\r\n\r\nretry: " +
                                std::to_string(kRetryMs) + "\n\n")) {
    return 200;
  }
  while (!reader->stopped()) {
    // A write that fails (the browser left, or stopped reading for write_timeout) ends the stream.
    for (const Event& event : reader->next(kReaderWait)) {
      if (!writeAll(connection, sseFrame(event))) return 200;
    }
  }
  return 200;
}

int WebServer::serveMetrics(mg_connection* connection, void* self) {
  const auto& server = *static_cast<WebServer*>(self);
  if (!server.options_.metrics_text) {
    mg_send_http_error(connection, 404, "%s", "this view keeps no metrics\n");
    return 404;
  }
  const std::string body = server.options_.metrics_text();
  mg_send_http_ok(connection, "text/plain; version=0.0.4", static_cast<long long>(body.size()));
  mg_write(connection, body.data(), body.size());
  return 200;
}

}  // namespace fogmap::view
