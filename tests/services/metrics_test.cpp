#include "services/common/metrics.hpp"

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

namespace fogmap {
namespace {

// GET /metrics over a plain socket, the way a Prometheus server scrapes. Returns the whole
// response (status line, headers, body), or an empty string when the exchange fails.
std::string httpGet(int port, const std::string& path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return {};
  // Bounds every read and write: a test must not hang on a silent server.
  timeval timeout{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string response;
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) {
    const std::string request = "GET " + path + " HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
    if (::send(fd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
      char buffer[4096];
      // HTTP/1.0: the server closes the connection after the body. Bounded by size and timeout.
      for (int reads = 0; reads < 10000; ++reads) {
        const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
        if (n <= 0) break;
        response.append(buffer, static_cast<std::size_t>(n));
      }
    }
  }
  ::close(fd);
  return response;
}

std::string body(const std::string& response) {
  const auto at = response.find("\r\n\r\n");
  return at == std::string::npos ? std::string() : response.substr(at + 4);
}

using LabelSet = std::map<std::string, std::string>;

// The value of the sample `name{labels}` in exposition text; label order does not matter, but the
// label set must match exactly.
std::optional<double> sample(const std::string& text, const std::string& name, const LabelSet& labels) {
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.empty() || line[0] == '#') continue;
    const auto brace = line.find('{');
    const auto space = line.rfind(' ');
    if (space == std::string::npos) continue;
    const std::string metric = line.substr(0, std::min(brace, space));
    if (metric != name) continue;
    LabelSet found;
    if (brace != std::string::npos) {
      const auto close = line.find('}', brace);
      std::string rest = line.substr(brace + 1, close - brace - 1);
      std::size_t pos = 0;
      while (pos < rest.size()) {
        const auto eq = rest.find('=', pos);
        const auto q1 = rest.find('"', eq);
        const auto q2 = rest.find('"', q1 + 1);
        if (eq == std::string::npos || q1 == std::string::npos || q2 == std::string::npos) break;
        found[rest.substr(pos, eq - pos)] = rest.substr(q1 + 1, q2 - q1 - 1);
        pos = q2 + 2;  // skip the closing quote and the comma
      }
    }
    // Histogram bucket bounds are compared as numbers ("0.001" vs "1e-03").
    if (labels.count("le") != 0 && found.count("le") != 0) {
      if (std::stod(labels.at("le")) != std::stod(found.at("le"))) continue;
      found["le"] = labels.at("le");
    }
    if (found == labels) return std::stod(line.substr(space + 1));
  }
  return std::nullopt;
}

LabelSet withBase(LabelSet extra = {}) {
  extra["service"] = "edge-cluster";
  extra["node"] = "n7";
  return extra;
}

TEST(Metrics, ServesExpositionTextWithLabelsAndValues) {
  Metrics metrics("127.0.0.1:0", "edge-cluster", "n7");
  const int port = metrics.listeningPort();
  ASSERT_GT(port, 0);

  metrics.bytesSent("parent", "map", 300);
  metrics.bytesSent("parent", "map", 200);
  metrics.bytesSent("parent", "points", 1200);
  metrics.bytesReceived("child-3", "map", 42);
  metrics.mapsIn(3);
  metrics.mapsOut();
  metrics.pointsIn(1000);
  metrics.pointsOut(250);
  metrics.clusteringSeconds(0.02);
  metrics.mergeSeconds(0.0003);
  metrics.mergeSeconds(0.7);
  metrics.pairs(10, 90);
  metrics.endToEndSeconds(0.15);
  metrics.childrenLive(3);
  metrics.childrenStale(1);
  metrics.malformed("map");
  metrics.malformed("map");
  metrics.malformed("points");
  metrics.lateMaps(2);
  metrics.reconnects();
  metrics.droppedUploads();
  metrics.framesProcessed();
  metrics.framesProcessed();
  metrics.droppedPoints("non_finite", 7);
  metrics.droppedPoints("non_finite", 5);
  metrics.geofencesDenied();
  metrics.periodSeconds(0.1);
  metrics.globalObjects(12);
  metrics.sensorMissing("edge-1", false);
  metrics.sensorMissing("edge-2", true);
  metrics.baselineBytes(1000);
  metrics.baselineBytes(24);

  const std::string response = httpGet(port, "/metrics");
  ASSERT_NE(response.find(" 200 "), std::string::npos) << response.substr(0, 200);
  const std::string text = body(response);

  EXPECT_EQ(sample(text, "fogmap_bytes_sent_total", withBase({{"peer", "parent"}, {"kind", "map"}})), 500.0);
  EXPECT_EQ(sample(text, "fogmap_bytes_sent_total", withBase({{"peer", "parent"}, {"kind", "points"}})), 1200.0);
  EXPECT_EQ(sample(text, "fogmap_bytes_received_total", withBase({{"peer", "child-3"}, {"kind", "map"}})), 42.0);
  EXPECT_EQ(sample(text, "fogmap_maps_in_total", withBase()), 3.0);
  EXPECT_EQ(sample(text, "fogmap_maps_out_total", withBase()), 1.0);
  EXPECT_EQ(sample(text, "fogmap_points_in_total", withBase()), 1000.0);
  EXPECT_EQ(sample(text, "fogmap_points_out_total", withBase()), 250.0);
  EXPECT_EQ(sample(text, "fogmap_clustering_seconds_count", withBase()), 1.0);
  EXPECT_EQ(sample(text, "fogmap_merge_seconds_count", withBase()), 2.0);
  EXPECT_NEAR(sample(text, "fogmap_merge_seconds_sum", withBase()).value_or(-1), 0.7003, 1e-9);
  EXPECT_EQ(sample(text, "fogmap_merge_seconds_bucket", withBase({{"le", "0.0001"}})), 0.0);
  EXPECT_EQ(sample(text, "fogmap_merge_seconds_bucket", withBase({{"le", "0.0005"}})), 1.0);
  EXPECT_EQ(sample(text, "fogmap_merge_seconds_bucket", withBase({{"le", "1"}})), 2.0);
  EXPECT_EQ(sample(text, "fogmap_merge_pairs_tested_total", withBase()), 10.0);
  EXPECT_EQ(sample(text, "fogmap_merge_pairs_pruned_total", withBase()), 90.0);
  EXPECT_EQ(sample(text, "fogmap_end_to_end_seconds_bucket", withBase({{"le", "0.1"}})), 0.0);
  EXPECT_EQ(sample(text, "fogmap_end_to_end_seconds_bucket", withBase({{"le", "0.25"}})), 1.0);
  EXPECT_EQ(sample(text, "fogmap_end_to_end_seconds_bucket", withBase({{"le", "2"}})), 1.0);
  EXPECT_EQ(sample(text, "fogmap_children_live", withBase()), 3.0);
  EXPECT_EQ(sample(text, "fogmap_children_stale", withBase()), 1.0);
  EXPECT_EQ(sample(text, "fogmap_malformed_inputs_total", withBase({{"what", "map"}})), 2.0);
  EXPECT_EQ(sample(text, "fogmap_malformed_inputs_total", withBase({{"what", "points"}})), 1.0);
  EXPECT_EQ(sample(text, "fogmap_late_maps_total", withBase()), 2.0);
  EXPECT_EQ(sample(text, "fogmap_reconnects_total", withBase()), 1.0);
  EXPECT_EQ(sample(text, "fogmap_dropped_uploads_total", withBase()), 1.0);
  EXPECT_EQ(sample(text, "fogmap_frames_total", withBase()), 2.0);
  EXPECT_EQ(sample(text, "fogmap_dropped_points_total", withBase({{"reason", "non_finite"}})), 12.0);
  EXPECT_EQ(sample(text, "fogmap_geofence_denied_total", withBase()), 1.0);
  EXPECT_EQ(sample(text, "fogmap_period_seconds", withBase()), 0.1);
  EXPECT_EQ(sample(text, "fogmap_global_objects", withBase()), 12.0);
  EXPECT_EQ(sample(text, "fogmap_sensor_missing", withBase({{"sensor", "edge-1"}})), 0.0);
  EXPECT_EQ(sample(text, "fogmap_sensor_missing", withBase({{"sensor", "edge-2"}})), 1.0);
  EXPECT_EQ(sample(text, "fogmap_baseline_equivalent_bytes_total", withBase()), 1024.0);
  // Labelled counters exist at 0 before the first event, so rates and alerts have data.
  EXPECT_EQ(sample(text, "fogmap_refused_uploads_total", withBase({{"reason", "clock_skew"}})), 0.0);
  EXPECT_EQ(sample(text, "fogmap_refused_uploads_total", withBase({{"reason", "unknown_peer"}})), 0.0);
  EXPECT_EQ(sample(text, "fogmap_malformed_inputs_total", withBase({{"what", "scan"}})), 0.0);

  // Every family is documented and typed.
  for (const std::string name :
       {"fogmap_bytes_sent_total", "fogmap_bytes_received_total", "fogmap_maps_in_total", "fogmap_maps_out_total",
        "fogmap_points_in_total", "fogmap_points_out_total", "fogmap_merge_pairs_tested_total",
        "fogmap_merge_pairs_pruned_total", "fogmap_malformed_inputs_total", "fogmap_late_maps_total",
        "fogmap_reconnects_total", "fogmap_dropped_uploads_total", "fogmap_frames_total",
        "fogmap_dropped_points_total", "fogmap_geofence_denied_total", "fogmap_baseline_equivalent_bytes_total",
        "fogmap_refused_uploads_total"}) {
    EXPECT_NE(text.find("# HELP " + name + " "), std::string::npos) << name;
    EXPECT_NE(text.find("# TYPE " + name + " counter"), std::string::npos) << name;
  }
  for (const std::string name : {"fogmap_clustering_seconds", "fogmap_merge_seconds", "fogmap_end_to_end_seconds"}) {
    EXPECT_NE(text.find("# TYPE " + name + " histogram"), std::string::npos) << name;
  }
  for (const std::string name : {"fogmap_children_live", "fogmap_children_stale", "fogmap_period_seconds",
                                 "fogmap_global_objects", "fogmap_sensor_missing"}) {
    EXPECT_NE(text.find("# TYPE " + name + " gauge"), std::string::npos) << name;
  }
}

TEST(Metrics, MergeHistogramHasBucketsFromTenthOfMillisecondToOneSecond) {
  Metrics metrics("127.0.0.1:0", "merge-aggregator", "n1");
  const std::string text = body(httpGet(metrics.listeningPort(), "/metrics"));
  const LabelSet base{{"service", "merge-aggregator"}, {"node", "n1"}};
  for (const std::string le : {"0.0001", "0.00025", "0.0005", "0.001", "0.0025", "0.005", "0.01", "0.025", "0.05",
                               "0.1", "0.25", "0.5", "1"}) {
    LabelSet labels = base;
    labels["le"] = le;
    EXPECT_EQ(sample(text, "fogmap_merge_seconds_bucket", labels), 0.0) << "le " << le;
  }
}

TEST(Metrics, WithoutBindAddressServesNothingButCounts) {
  Metrics metrics("", "tracker", "n2");
  EXPECT_EQ(metrics.listeningPort(), 0);
  metrics.framesProcessed();
  bool found = false;
  for (const auto& family : metrics.registry().Collect()) {
    if (family.name != "fogmap_frames_total") continue;
    ASSERT_EQ(family.metric.size(), 1U);
    EXPECT_EQ(family.metric[0].counter.value, 1.0);
    found = true;
  }
  EXPECT_TRUE(found);
}

// A service exits promptly: the HTTP server, just woken by a scrape, would otherwise sleep up to
// 2 s before it notices the stop.
TEST(Metrics, StopsServingWithinMilliseconds) {
  auto metrics = std::make_unique<Metrics>("127.0.0.1:0", "merge-aggregator", "sink");
  const int port = metrics->listeningPort();
  ASSERT_GT(port, 0);
  ASSERT_NE(httpGet(port, "/metrics").find(" 200 "), std::string::npos);
  const auto start = std::chrono::steady_clock::now();
  metrics.reset();
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_LT(took, std::chrono::milliseconds(500))
      << std::chrono::duration_cast<std::chrono::milliseconds>(took).count() << " ms";
  EXPECT_EQ(httpGet(port, "/metrics"), "") << "still served after the destructor";
}

TEST(Metrics, RefusesAnAddressInUse) {
  Metrics first("127.0.0.1:0", "edge-cluster", "n7");
  ASSERT_GT(first.listeningPort(), 0);
  EXPECT_THROW(Metrics("127.0.0.1:" + std::to_string(first.listeningPort()), "edge-cluster", "n8"),
               std::runtime_error);
}

// A port held by another process (here: a plain listening socket) gives an error naming the
// address and saying it is in use, not civetweb's "null context when constructing CivetServer".
TEST(Metrics, NamesTheAddressWhenThePortIsInUse) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const std::string address = "127.0.0.1:" + std::to_string(ntohs(addr.sin_port));

  std::string message;
  try {
    Metrics metrics(address, "edge-cluster", "n7");
  } catch (const std::runtime_error& e) {
    message = e.what();
  }
  ::close(fd);
  EXPECT_NE(message.find(address), std::string::npos) << message;
  EXPECT_NE(message.find("in use"), std::string::npos) << message;
  EXPECT_EQ(message.find("null context"), std::string::npos) << message;
}

}  // namespace
}  // namespace fogmap
