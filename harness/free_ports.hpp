#pragma once
// Loopback ports chosen free at run time (never fixed numbers that another run or service could
// hold): for clusters that fogctl starts on its own (eval, demo) and for the tests.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "common/config/topology.hpp"

namespace fogmap::harness {


// Ports the kernel hands out as free on 127.0.0.1 right now, distinct (held together until all
// are chosen). Throws when the kernel has none to give.
inline std::vector<std::uint16_t> freePorts(std::size_t count) {
  std::vector<int> fds;
  std::vector<std::uint16_t> ports;
  const auto close_all = [&] {
    for (const int fd : fds) ::close(fd);
  };
  for (std::size_t i = 0; i < count; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) {
      close_all();
      throw std::runtime_error("cannot open a socket to find a free port");
    }
    fds.push_back(fd);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof addr;
    if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
      close_all();
      throw std::runtime_error("cannot bind 127.0.0.1:0 to find a free port");
    }
    ports.push_back(ntohs(addr.sin_port));
  }
  close_all();
  return ports;
}

// Gives every node of the topology a free gRPC port (aggregators, trackers) and metrics port.
inline void useFreePorts(TopologyConfig& topology) {
  const auto ports = freePorts(2 * topology.nodes.size());
  std::size_t next = 0;
  for (auto& node : topology.nodes) {
    if (node.role == Role::kAggregator || node.role == Role::kTracker) node.port = ports[next];
    ++next;
    node.metrics_port = ports[next++];
  }
}

}  // namespace fogmap::harness
