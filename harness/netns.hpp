#pragma once
// A network namespace joined to the host by a veth pair, for faults no signal can make: a link
// whose packets are silently dropped (iptables DROP inside the namespace), with no FIN and no
// RST; and for links of limited rate (tbf on both ends of the pair). Needs root (CAP_NET_ADMIN),
// `ip` (iproute2), `iptables` for dropping and `tc` (iproute2) for rates; errors say which is missing.
//
// Address plan, all inside 10.213.0.0/16, one /30 per pair: pair `index` of octet X is
// 10.213.X.(4 index + 1) on the host side and 10.213.X.(4 index + 2) in the namespace (index < 64).
// create(tag) is pair 0 of octet tag % 250 (10.213.N.1 and 10.213.N.2); sets of pairs
// (shaped_links.hpp) take a whole octet no address of the host is in, 250..255 first.
//
// The namespace's default route goes via the host side: a process inside reaches every address of
// the host (the host side of any other pair too) by local delivery on the host, which needs no
// ip_forward; other namespaces stay out of reach (that would be forwarding).
#include <string>
#include <vector>

#include "common/base/status.hpp"

namespace fogmap::harness {

// One /30 of the address plan above.
struct PairAddress {
  unsigned octet = 0;  // third octet of 10.213.0.0/16, < 256
  unsigned index = 0;  // the pair within the octet, < kPairsPerOctet
};
inline constexpr unsigned kPairsPerOctet = 64;

class NetnsLink {
 public:
  // Creates the namespace and the pair; `tag` keeps concurrent runs apart (e.g. the pid). Checks
  // that iptables works inside (setDropping needs it).
  static Expected<NetnsLink> create(unsigned tag);
  // Pair `address.index` of a set: namespace fogmap-TAG-INDEX at the plan's addresses. Needs `ip`
  // only (iptables is not checked).
  static Expected<NetnsLink> create(unsigned tag, PairAddress address);
  NetnsLink(NetnsLink&& other) noexcept;
  NetnsLink& operator=(NetnsLink&&) = delete;
  ~NetnsLink();  // deletes the host side of the pair and the namespace

  const std::string& name() const { return name_; }  // the namespace (/var/run/netns/NAME)
  const std::string& hostAddress() const { return host_ip_; }
  const std::string& namespaceAddress() const { return ns_ip_; }
  // The command prefix that runs a program inside the namespace.
  std::vector<std::string> prefix() const;
  // Drops every packet in and out of the namespace (true), or stops dropping (false).
  Status setDropping(bool drop);
  // Limits both directions to `mbit_per_s` (10^6 bit/s): a tbf as root qdisc of the namespace
  // side (what leaves the namespace: uploads) and of the host side (what enters it: replies).
  // Bucket (burst): 10 ms at the rate, at least two full 1514-byte frames: 12.5 kB at 10 Mbit/s.
  // tbf drops a packet larger than its bucket, and a bucket of a few frames keeps the long-run
  // rate exact (at most 10 ms of traffic pass at line speed). Queue (latency): 50 ms at the rate
  // plus the bucket, 75 kB at 10 Mbit/s: enough for TCP to keep the link busy, short enough that
  // a link offered more than it carries shows loss and backoff, not seconds of queueing.
  // Replaces an earlier rate. Needs `tc`.
  Status setRate(double mbit_per_s);
  // Removes the rate limit of both ends (no error when there was none).
  Status clearRate();

 private:
  NetnsLink(std::string name, std::string host_ip, std::string ns_ip)
      : name_(std::move(name)), host_ip_(std::move(host_ip)), ns_ip_(std::move(ns_ip)) {}
  static Expected<NetnsLink> make(const std::string& name, const std::string& host_if, const std::string& ns_if,
                                  const std::string& subnet_prefix, unsigned first_host, bool check_iptables);
  std::string name_;
  std::string host_ip_;
  std::string ns_ip_;
  std::string host_if_;  // set once the pair exists: the destructor deletes only what was made
  std::string ns_if_;
};

// Runs a program (searched on PATH) with its output discarded; an error naming the command (and
// what it wrote to stderr) when it cannot be started, does not exit 0, or runs longer than 15 s
// (then it is killed).
Status runProgram(const std::vector<std::string>& argv);
// The program's full path on PATH (or /usr/sbin, /sbin), or empty.
std::string findProgram(const std::string& name);

}  // namespace fogmap::harness
