// fogctl view's runtime against a fake root served by real gRPC, read by a page over real HTTP:
// the root's maps become map events, its loss and return become status events, and a malformed map
// is refused and counted.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include <nlohmann/json.hpp>

#include "harness/cluster_run.hpp"
#include "services/common/grpc_options.hpp"
#include "tests/support/fake_root.hpp"
#include "tests/support/global_maps.hpp"
#include "tests/support/http_client.hpp"
#include "view/view_runtime.hpp"

namespace fogmap::view {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;
using test_support::FakeRoot;
using test_support::globalMapWith;
using test_support::serveFakeRoot;
using test_support::SseClient;

// The next status event whose root link is (or is not) connected.
std::optional<json> rootStatus(SseClient& page, bool connected) {
  while (auto status = page.next("status", 30s)) {
    const json s = json::parse(status->second);
    if (s["root"]["connected"].get<bool>() == connected) return s;
  }
  return std::nullopt;
}

TEST(ViewRuntime, FollowsTheRootAcrossARestartAndRefusesAMalformedMap) {
  int port = 0;
  auto root = std::make_unique<FakeRoot>();
  auto server = serveFakeRoot(*root, port);
  ASSERT_NE(port, 0);
  ViewConfig config;
  config.topology = "runtime-test";
  config.nodes = {{1, "edge-1", "edge"}};
  ViewOptions options;
  options.web.port = 0;
  options.heartbeat = 100ms;
  const std::string target = "127.0.0.1:" + std::to_string(port);
  auto runtime = ViewRuntime::start(config, FeedTarget{target, channelCredentials(std::nullopt)}, std::nullopt, options);
  ASSERT_TRUE(runtime) << runtime.error().message;
  SseClient page((*runtime)->port());
  const auto first = page.next("config", 10s);
  ASSERT_TRUE(first);
  EXPECT_EQ(json::parse(first->second)["topology"], "runtime-test");

  ASSERT_TRUE(root->waitForSubscriptions(1));
  GlobalMapMessage g = globalMapWith(1, {{1, 2, 0.5}});
  g.header.epoch = 7;
  g.header.contributing_nodes = {1};
  root->send(g);
  const auto map = page.next("map", 30s);
  ASSERT_TRUE(map);
  const json m = json::parse(map->second);
  EXPECT_EQ(m["epoch"], 7);
  ASSERT_EQ(m["objects"].size(), 1U);
  EXPECT_EQ(m["objects"][0]["sensors"], json::array({"edge-1"}));
  const auto up = rootStatus(page, true);
  ASSERT_TRUE(up);
  EXPECT_EQ((*up)["root"]["target"], target);
  EXPECT_TRUE((*up)["tracker"].is_null());

  // The root goes away: the page hears why; a new root on the same port: connected again.
  root->close();
  server->Shutdown(std::chrono::system_clock::now() + 200ms);
  server.reset();
  const auto down = rootStatus(page, false);
  ASSERT_TRUE(down);
  EXPECT_NE((*down)["root"]["detail"].get<std::string>().find("retrying"), std::string::npos) << *down;
  auto second = std::make_unique<FakeRoot>();
  auto server2 = serveFakeRoot(*second, port);
  ASSERT_TRUE(server2 != nullptr);
  ASSERT_TRUE(second->waitForSubscriptions(1, 30s));
  GlobalMapMessage broken = globalMapWith(2, {{1, 1, 1}});
  broken.map.objects[0].ellipsoids[0].shape(0, 0) = -1.0;  // not positive definite: refused
  second->send(broken);
  g.header.epoch = 9;
  second->send(g);
  const auto again = page.next("map", 30s);
  ASSERT_TRUE(again);
  EXPECT_EQ(json::parse(again->second)["epoch"], 9) << "the malformed map of epoch 8 never reaches the page";
  ASSERT_TRUE(rootStatus(page, true));

  const auto metrics = test_support::httpRequest((*runtime)->port(), "/metrics");
  ASSERT_EQ(metrics.status, 200);
  // Only the root's stream: each family's sum is the root's.
  EXPECT_EQ(harness::sumMetric(metrics.body, "fogmap_view_refused_messages_total"), 1.0);
  EXPECT_EQ(harness::sumMetric(metrics.body, "fogmap_view_messages_total"), 2.0);
  EXPECT_GE(harness::sumMetric(metrics.body, "fogmap_view_link_losses_total"), 1.0);
  EXPECT_EQ(harness::sumMetric(metrics.body, "fogmap_view_pages"), 1.0);
  second->close();
  server2->Shutdown(std::chrono::system_clock::now() + 200ms);
}

}  // namespace
}  // namespace fogmap::view
