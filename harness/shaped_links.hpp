#pragma once
// Every edge behind a rate-limited link (Fig. 9 of the MAD-C paper: the sensors' links limited to
// 10 Mbit/s). Each edge runs in its own network namespace joined to the host by its own veth pair
// (netns.hpp), both ends of which carry a tbf of the given rate: the edge's uploads and what its
// parent sends back go through that one shaped link.
//
// Where the others are: an aggregator with edge children listens on the host side of its first
// edge's pair. A namespace's default route goes via its own pair's host side, so every edge
// reaches its parent (an address of the host: local delivery, no ip_forward) through its own
// shaped link, whichever pair's address the parent holds. Aggregator-to-aggregator links stay on
// the host, unshaped (aggregators without edge children keep their host): the paper limits the
// sensors' links. The host reaches every namespace address through its pair, so the launcher's
// /metrics polls and a subscription to the root work as without shaping.
// With TLS, certificates that name IP addresses must name the rewritten ones.
#include <map>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "harness/netns.hpp"

namespace fogmap::harness {

// Whether shaped links can be made here: root (CAP_NET_ADMIN), `ip` and `tc` (iproute2), network
// namespaces, veth pairs and the tbf qdisc, tried in a scratch namespace that is deleted again.
// The error says what is missing or refused.
Status shapingAvailable();

class ShapedLinks {
 public:
  // One namespace and pair per edge of `topology` (at most kPairsPerOctet edges), all in one
  // octet of 10.213.0.0/16 that no address of the host is in (taken under a lock, so concurrent
  // runs get different octets); `tag` (e.g. the pid) names the namespaces fogmap-TAG-INDEX.
  // Both ends of every pair are limited to `mbit_per_s`. On error nothing is left behind.
  static Expected<ShapedLinks> create(const TopologyConfig& topology, double mbit_per_s, unsigned tag);
  ShapedLinks(ShapedLinks&&) noexcept = default;
  ShapedLinks& operator=(ShapedLinks&&) = delete;
  // Deletes every pair and namespace (each command bounded by runProgram's timeout). Destroy it
  // after the processes inside have stopped.
  ~ShapedLinks() = default;

  // The topology with each edge's host its namespace address and each parent of edges on the
  // host side of its first edge's pair; everything else as given.
  const TopologyConfig& topology() const { return topology_; }
  // StartOptions::prefixes: each edge runs under `ip netns exec` of its namespace.
  const std::map<std::string, std::vector<std::string>>& prefixes() const { return prefixes_; }
  // The pair of an edge; nullptr for a name that is not an edge of the topology.
  const NetnsLink* link(const std::string& edge) const;
  NetnsLink* link(const std::string& edge);  // e.g. to change its rate while the cluster runs
  double rateMbitPerS() const { return mbit_per_s_; }

 private:
  ShapedLinks(TopologyConfig topology, double mbit_per_s) : topology_(std::move(topology)), mbit_per_s_(mbit_per_s) {}
  TopologyConfig topology_;
  double mbit_per_s_ = 0.0;
  std::vector<NetnsLink> links_;   // one per edge, in the topology's order of edges
  std::map<std::string, std::size_t> link_of_;  // edge name -> index into links_
  std::map<std::string, std::vector<std::string>> prefixes_;
};

}  // namespace fogmap::harness
