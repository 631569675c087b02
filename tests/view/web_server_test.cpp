// The view's web server, real civetweb on loopback: the page, its events, its bounds, and a browser
// that stops reading.
#include <gtest/gtest.h>

#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

#include "tests/support/http_client.hpp"
#include "view/web_server.hpp"

namespace fogmap::view {
namespace {

using namespace std::chrono_literals;
using test_support::httpRequest;
using test_support::SseClient;

std::unique_ptr<WebServer> startServer(EventHub& hub, WebServerOptions options = {}) {
  options.port = 0;
  auto server = WebServer::start(options, hub);
  if (!server) ADD_FAILURE() << server.error().message;
  return server ? std::move(*server) : nullptr;
}

TEST(WebServer, ServesThePageItsFilesAndNothingElse) {
  EventHub hub(4);
  WebServerOptions options;
  options.metrics_text = [] { return std::string("fogmap_view_pages 0\n"); };
  auto server = startServer(hub, options);
  ASSERT_TRUE(server);
  EXPECT_NE(server->port(), 0);
  EXPECT_EQ(server->url(), "http://127.0.0.1:" + std::to_string(server->port()) + "/");
  const auto page = httpRequest(server->port(), "/");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.headers.find("text/html"), std::string::npos);
  EXPECT_NE(page.body.find("fogmap-state"), std::string::npos);  // the test hook of the page
  EXPECT_EQ(httpRequest(server->port(), "/index.html").body, page.body);
  const auto script = httpRequest(server->port(), "/view.js");
  EXPECT_EQ(script.status, 200);
  EXPECT_NE(script.headers.find("text/javascript"), std::string::npos);
  EXPECT_NE(script.body.find("EventSource"), std::string::npos);
  EXPECT_EQ(httpRequest(server->port(), "/view.css").status, 200);
  EXPECT_EQ(httpRequest(server->port(), "/metrics").body, "fogmap_view_pages 0\n");
  EXPECT_EQ(httpRequest(server->port(), "/../etc/passwd").status, 404);
  EXPECT_EQ(httpRequest(server->port(), "/nothing").status, 404);
  EXPECT_EQ(httpRequest(server->port(), "/", "POST").status, 405);
}

TEST(WebServer, ThePageAndItsScriptAreSmall) {
  std::size_t bytes = 0;
  for (const auto& asset : webAssets()) bytes += asset.body.size();
  EXPECT_LE(bytes, 300U * 1000U);  // the issue's bound, JavaScript and CSS and HTML together
}

TEST(WebServer, ListensOnTheGivenAddressOnly) {
  EventHub hub(4);
  auto server = startServer(hub);
  ASSERT_TRUE(server);
  const int there = test_support::connectTo("127.0.0.1", server->port());
  EXPECT_GE(there, 0);
  if (there >= 0) ::close(there);
  // Another address of the loopback network: nothing listens there.
  const int elsewhere = test_support::connectTo("127.0.0.2", server->port());
  EXPECT_LT(elsewhere, 0);
  if (elsewhere >= 0) ::close(elsewhere);
  WebServerOptions bad;
  bad.address = "localhost";
  EXPECT_FALSE(WebServer::start(bad, hub));
  // The port in use: an error naming it, not a crash.
  WebServerOptions taken;
  taken.port = server->port();
  const auto second = WebServer::start(taken, hub);
  ASSERT_FALSE(second);
  EXPECT_NE(second.error().message.find(std::to_string(server->port())), std::string::npos);
}

TEST(WebServer, StreamsTheNewestEventsAndRefusesPagesBeyondTheBound) {
  EventHub hub(2);
  auto server = startServer(hub);
  ASSERT_TRUE(server);
  hub.publish(EventKind::kConfig, R"({"topology":"t"})");
  SseClient page(server->port());
  ASSERT_TRUE(page.connected());
  const auto config = page.next("", 10s);
  ASSERT_TRUE(config);
  EXPECT_EQ(page.status(), 200);
  EXPECT_EQ(config->first, "config");
  EXPECT_EQ(config->second, R"({"topology":"t"})");
  hub.publish(EventKind::kMap, R"({"epoch":1})");
  const auto map = page.next("map", 10s);
  ASSERT_TRUE(map);
  EXPECT_EQ(map->second, R"({"epoch":1})");
  SseClient second(server->port());
  ASSERT_TRUE(second.next("config", 10s));
  SseClient third(server->port());  // one more than the hub's 2
  EXPECT_FALSE(third.next("", 10s));
  EXPECT_EQ(third.status(), 503);
  EXPECT_EQ(hub.refused(), 1U);
}

TEST(WebServer, ABrowserThatStopsReadingNeitherHoldsThePublisherNorTheOtherPagesAndIsDropped) {
  EventHub hub(4);
  WebServerOptions options;
  options.write_timeout = std::chrono::seconds(2);
  auto server = startServer(hub, options);
  ASSERT_TRUE(server);
  // A page that reads nothing: its socket buffers fill, then its writes wait.
  const int stuck = test_support::connectTo("127.0.0.1", server->port());
  ASSERT_GE(stuck, 0);
  ASSERT_TRUE(test_support::sendRequest(stuck, "GET", "/events"));
  SseClient reading(server->port());
  ASSERT_TRUE(reading.connected());
  const auto joined = std::chrono::steady_clock::now() + 30s;
  while (hub.clients() < 2 && std::chrono::steady_clock::now() < joined) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(hub.clients(), 2U) << "both pages read events";
  // Maps of 64 kB keep coming while the reading page reads and the stuck one reads nothing, until
  // the stuck page's buffers are full and its write has waited write_timeout: it is dropped and
  // its place freed (however fast this machine writes, reads or publishes).
  const std::string padding(64 * 1024, 'x');
  int published = 0;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (hub.clients() > 1 && std::chrono::steady_clock::now() < deadline) {
    hub.publish(EventKind::kMap, "{\"epoch\":" + std::to_string(++published) + ",\"pad\":\"" + padding + "\"}");
    while (reading.next("map", 1ms)) {  // the reading page reads all it has been sent
    }
  }
  EXPECT_EQ(hub.clients(), 1U) << "the page that stopped reading still holds a place after " << published << " maps";
  // The publisher was never held, and the reading page still gets the newest map.
  hub.publish(EventKind::kMap, R"({"epoch":"last"})");
  bool got_last = false;
  while (auto map = reading.next("map", 30s)) {
    if (map->second == R"({"epoch":"last"})") {
      got_last = true;
      break;
    }
  }
  EXPECT_TRUE(got_last);
  ::close(stuck);
}

}  // namespace
}  // namespace fogmap::view
