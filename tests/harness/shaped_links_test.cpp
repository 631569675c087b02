// Shaped links (harness/shaped_links.hpp, NetnsLink::setRate): real network namespaces, veth
// pairs and tbf, as root. Where they cannot be made (no root, no ip/tc, namespaces refused) the
// tests that need them are skipped with the reason. Whole clusters behind shaped links are process
// clusters: tests/integration/shaped_cluster_test.cpp.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/config/topology.hpp"
#include "common/config/topology_presets.hpp"
#include "harness/launcher.hpp"
#include "harness/shaped_links.hpp"
#include "tests/support/shaping.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using harness::NetnsLink;
using harness::ShapedLinks;

using test_support::kittiSequenceDir;
constexpr double kRateMbitPerS = test_support::kShapedRateMbitPerS;

// ---- a bulk transfer across one pair ----

constexpr std::size_t kTransferBytes = 2'500'000;  // 2.0 s at 10 Mbit/s

enum class Direction { kUpload, kDownload };  // namespace -> host (the edge's uploads), host -> namespace

struct Transfer {
  std::size_t bytes = 0;  // what the receiver got
  double seconds = 0.0;   // the receiver's time from the connection to the last byte
  std::string error;
};

// A TCP socket whose every call gives up after 15 s: no transfer below can hang.
int boundedSocket() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  const timeval limit{15, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &limit, sizeof limit);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &limit, sizeof limit);
  return fd;
}

sockaddr_in ipv4(const std::string& ip, std::uint16_t port) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  ::inet_pton(AF_INET, ip.c_str(), &addr.sin_addr);
  return addr;
}

bool sendAll(int fd, std::size_t bytes) {
  const std::vector<char> chunk(64 * 1024, 'x');
  while (bytes > 0) {
    const ssize_t n = ::send(fd, chunk.data(), std::min(bytes, chunk.size()), MSG_NOSIGNAL);
    if (n <= 0) return false;
    bytes -= static_cast<std::size_t>(n);
  }
  return ::shutdown(fd, SHUT_WR) == 0;
}

// Reads until the peer closes (or a call times out); the bytes and the seconds it took.
std::pair<std::size_t, double> receiveAll(int fd) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<char> buffer(64 * 1024);
  std::size_t total = 0;
  for (ssize_t n = 0; (n = ::recv(fd, buffer.data(), buffer.size(), 0)) > 0;) total += static_cast<std::size_t>(n);
  return {total, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
}

// kTransferBytes across the pair: the host listens on the pair's host side, a thread that joined
// the namespace (setns: no helper program needed) connects from inside.
Transfer transfer(const NetnsLink& link, Direction direction) {
  Transfer result;
  const int listener = boundedSocket();
  sockaddr_in addr = ipv4(link.hostAddress(), 0);
  socklen_t len = sizeof addr;
  if (::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(listener, 1) != 0 ||
      ::getsockname(listener, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    ::close(listener);
    result.error = "cannot listen on " + link.hostAddress();
    return result;
  }
  const std::uint16_t port = ntohs(addr.sin_port);
  Transfer inside_result;
  std::thread inside([&] {
    // setns moves this thread only; the namespace's file is what `ip netns add` made.
    const int ns = ::open(("/var/run/netns/" + link.name()).c_str(), O_RDONLY | O_CLOEXEC);
    if (ns < 0 || ::setns(ns, CLONE_NEWNET) != 0) {
      if (ns >= 0) ::close(ns);
      inside_result.error = "cannot join namespace " + link.name();
      return;
    }
    ::close(ns);
    const int fd = boundedSocket();
    const sockaddr_in server = ipv4(link.hostAddress(), port);
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&server), sizeof server) != 0) {
      inside_result.error = "cannot connect from the namespace to " + link.hostAddress();
    } else if (direction == Direction::kUpload) {
      if (!sendAll(fd, kTransferBytes)) inside_result.error = "upload interrupted";
    } else {
      std::tie(inside_result.bytes, inside_result.seconds) = receiveAll(fd);
    }
    ::close(fd);
  });
  const int conn = ::accept4(listener, nullptr, nullptr, SOCK_CLOEXEC);  // SO_RCVTIMEO bounds it
  if (conn < 0) {
    result.error = "no connection from the namespace";
  } else if (direction == Direction::kUpload) {
    std::tie(result.bytes, result.seconds) = receiveAll(conn);
  } else if (!sendAll(conn, kTransferBytes)) {
    result.error = "download interrupted";
  }
  if (conn >= 0) ::close(conn);
  ::close(listener);
  inside.join();
  if (!inside_result.error.empty()) result.error = inside_result.error;
  if (direction == Direction::kDownload && result.error.empty()) {
    result.bytes = inside_result.bytes;
    result.seconds = inside_result.seconds;
  }
  return result;
}

void report(const char* what, const Transfer& t) {
  std::printf("[ measured ] %s: %zu bytes in %.3f s = %.2f Mbit/s\n", what, t.bytes, t.seconds,
              static_cast<double>(t.bytes) * 8.0 / 1e6 / t.seconds);
}

TEST(ShapedLinks, RefuseBadRatesAndMoreEdgesThanAnOctetHoldsBeforeMakingAnything) {
  const TopologyConfig star = makeStarTopology(3, kittiSequenceDir(), 40000);
  for (const double rate : {0.0, -10.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    const auto shaped = ShapedLinks::create(star, rate, static_cast<unsigned>(::getpid()));
    ASSERT_FALSE(shaped) << rate;
    EXPECT_EQ(shaped.error().code, ErrorCode::kInvalidArgument) << rate;
  }
  const auto crowded = ShapedLinks::create(makeStarTopology(static_cast<int>(harness::kPairsPerOctet) + 1, kittiSequenceDir(), 40000),
                                           kRateMbitPerS, static_cast<unsigned>(::getpid()));
  ASSERT_FALSE(crowded);
  EXPECT_EQ(crowded.error().code, ErrorCode::kResourceExhausted);
}

TEST(ShapedLinks, APairCarriesNoMoreThanItsRateEitherWayAndAllOnceCleared) {
  SKIP_UNLESS_SHAPING_IS_POSSIBLE();
  auto shaped = ShapedLinks::create(makeStarTopology(1, kittiSequenceDir(), 40000), kRateMbitPerS, static_cast<unsigned>(::getpid()));
  ASSERT_TRUE(shaped) << shaped.error().message;
  NetnsLink& link = *shaped->link("edge-1");

  // 2.5 MB at 10 Mbit/s take 2.0 s (plus headers); the bucket lets 12.5 kB through at once.
  for (const Direction d : {Direction::kUpload, Direction::kDownload}) {
    const Transfer t = transfer(link, d);
    ASSERT_TRUE(t.error.empty()) << t.error;
    report(d == Direction::kUpload ? "upload, 10 Mbit/s" : "download, 10 Mbit/s", t);
    EXPECT_EQ(t.bytes, kTransferBytes);
    EXPECT_GE(t.seconds, 1.6);
    EXPECT_LT(t.seconds, 8.0);  // shaped, not starved by a bucket too small for a frame
  }
  ASSERT_TRUE(link.clearRate());
  for (const Direction d : {Direction::kUpload, Direction::kDownload}) {
    const Transfer t = transfer(link, d);
    ASSERT_TRUE(t.error.empty()) << t.error;
    report(d == Direction::kUpload ? "upload, unshaped" : "download, unshaped", t);
    EXPECT_EQ(t.bytes, kTransferBytes);
    EXPECT_LT(t.seconds, 0.8);
  }
}

}  // namespace
}  // namespace fogmap
