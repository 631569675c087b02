#include "harness/shaped_links.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <set>
#include <thread>

namespace fogmap::harness {

namespace {

// Held while a set of pairs picks its octet and assigns its addresses, so that a concurrent run
// sees them before it picks.
class AddressPlanLock {
 public:
  static Expected<AddressPlanLock> acquire() {
    const std::filesystem::path dir = std::filesystem::is_directory("/run/lock") ? "/run/lock" : std::filesystem::temp_directory_path();
    const auto path = dir / "fogmap-netns.lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (fd < 0) return ioError("cannot open " + path.string());
    for (int attempt = 0; attempt < 1500; ++attempt) {  // 30 s: another run makes its pairs meanwhile
      if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return AddressPlanLock(fd);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ::close(fd);
    return resourceExhausted("another run held " + path.string() + " for 30 s");
  }
  AddressPlanLock(AddressPlanLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  AddressPlanLock& operator=(AddressPlanLock&&) = delete;
  ~AddressPlanLock() {
    if (fd_ >= 0) ::close(fd_);  // releases the lock
  }

 private:
  explicit AddressPlanLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

// Third octets of 10.213.0.0/16 that an address of the host is in.
Expected<std::set<unsigned>> octetsInUse() {
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return ioError("getifaddrs failed");
  std::set<unsigned> used;
  for (const ifaddrs* a = list; a != nullptr; a = a->ifa_next) {
    if (a->ifa_addr == nullptr || a->ifa_addr->sa_family != AF_INET) continue;
    const std::uint32_t ip = ntohl(reinterpret_cast<const sockaddr_in*>(a->ifa_addr)->sin_addr.s_addr);
    if ((ip >> 16U) == ((10U << 8U) | 213U)) used.insert((ip >> 8U) & 0xFFU);
  }
  ::freeifaddrs(list);
  return used;
}

// The first free octet: 250..255 first, which single links (NetnsLink::create(tag), octet tag %
// 250) never take, then 0..249.
Expected<unsigned> freeOctet() {
  auto used = octetsInUse();
  if (!used) return used.error();
  for (unsigned k = 0; k < 256; ++k) {
    const unsigned octet = (250U + k) % 256U;
    if (used->count(octet) == 0) return octet;
  }
  return resourceExhausted("every /24 of 10.213.0.0/16 holds an address of this host (leftover namespaces? ip netns list)");
}

Status validRate(double mbit_per_s) {
  if (!std::isfinite(mbit_per_s) || mbit_per_s <= 0.0 || mbit_per_s > 100000.0) {
    return invalidArgument("a link rate must be above 0 and at most 100000 Mbit/s, not " + std::to_string(mbit_per_s));
  }
  return {};
}

}  // namespace

Status shapingAvailable() {
  if (::geteuid() != 0) {
    return invalidArgument("shaped links need root (CAP_NET_ADMIN) for network namespaces; running as uid " +
                           std::to_string(::geteuid()));
  }
  for (const char* tool : {"ip", "tc"}) {
    if (findProgram(tool).empty()) return notFound(std::string("'") + tool + "' is not installed (iproute2)");
  }
  static std::atomic<unsigned> probes{0};
  const std::string name = "fogmap-probe-" + std::to_string(::getpid()) + "-" + std::to_string(probes++);
  const std::string ip = findProgram("ip");
  const std::string tc = findProgram("tc");
  if (auto s = runProgram({"ip", "netns", "add", name}); !s) {
    return Error{s.error().code, "network namespaces cannot be made here: " + s.error().message};
  }
  // Interface names are per namespace: the scratch pair cannot meet anyone else's.
  Status result;
  if (auto s = runProgram({"ip", "netns", "exec", name, ip, "link", "add", "fmprobe0", "type", "veth", "peer", "name", "fmprobe1"}); !s) {
    result = Error{s.error().code, "veth pairs cannot be made here: " + s.error().message};
  } else if (auto t = runProgram({"ip", "netns", "exec", name, tc, "qdisc", "replace", "dev", "fmprobe0", "root", "tbf",
                                  "rate", "10mbit", "burst", "12500", "latency", "50ms"});
             !t) {
    result = Error{t.error().code, "the tbf qdisc is not available (kernel module sch_tbf): " + t.error().message};
  }
  (void)runProgram({"ip", "netns", "del", name});
  return result;
}

Expected<ShapedLinks> ShapedLinks::create(const TopologyConfig& topology, double mbit_per_s, unsigned tag) {
  if (auto s = validRate(mbit_per_s); !s) return s.error();
  std::vector<const NodeConfig*> edges;
  for (const NodeConfig& n : topology.nodes) {
    if (n.role == Role::kEdge) edges.push_back(&n);
  }
  if (edges.size() > kPairsPerOctet) {
    return resourceExhausted("shaped links take one octet of 10.213.0.0/16: at most " + std::to_string(kPairsPerOctet) +
                             " edges, not " + std::to_string(edges.size()));
  }
  ShapedLinks shaped(topology, mbit_per_s);
  {
    auto lock = AddressPlanLock::acquire();
    if (!lock) return lock.error();
    auto octet = freeOctet();
    if (!octet) return octet.error();
    shaped.links_.reserve(edges.size());
    for (std::size_t i = 0; i < edges.size(); ++i) {
      auto link = NetnsLink::create(tag, PairAddress{*octet, static_cast<unsigned>(i)});
      if (!link) return Error{link.error().code, "edge " + edges[i]->name + "'s link: " + link.error().message};
      shaped.links_.push_back(std::move(*link));
      shaped.link_of_[edges[i]->name] = i;
    }
  }
  for (std::size_t i = 0; i < edges.size(); ++i) {
    if (auto s = shaped.links_[i].setRate(mbit_per_s); !s) {
      return Error{s.error().code, "edge " + edges[i]->name + "'s link: " + s.error().message};
    }
  }
  // An edge's parent takes the host side of its first edge's pair (in the topology's order).
  std::map<std::string, std::string> parent_host;
  for (const NodeConfig* e : edges) {
    parent_host.emplace(e->parent, shaped.links_[shaped.link_of_.at(e->name)].hostAddress());
  }
  for (NodeConfig& n : shaped.topology_.nodes) {
    if (n.role == Role::kEdge) {
      const NetnsLink& link = shaped.links_[shaped.link_of_.at(n.name)];
      n.host = link.namespaceAddress();
      shaped.prefixes_[n.name] = link.prefix();
    } else if (const auto it = parent_host.find(n.name); it != parent_host.end()) {
      n.host = it->second;
    }
  }
  return shaped;
}

const NetnsLink* ShapedLinks::link(const std::string& edge) const {
  const auto it = link_of_.find(edge);
  return it == link_of_.end() ? nullptr : &links_[it->second];
}

NetnsLink* ShapedLinks::link(const std::string& edge) {
  const auto it = link_of_.find(edge);
  return it == link_of_.end() ? nullptr : &links_[it->second];
}

}  // namespace fogmap::harness
