#pragma once
// A network namespace joined to the host by a veth pair, for faults no signal can make: a link
// whose packets are silently dropped (iptables DROP inside the namespace), with no FIN and no
// RST. Needs root (CAP_NET_ADMIN), `ip` (iproute2) and `iptables`; create() says which is missing.
// Traffic stays on the pair: 10.213.N.1 (host side) and 10.213.N.2 (namespace side), /30.
#include <string>
#include <vector>

#include "common/status.hpp"

namespace fogmap::cli {

class NetnsLink {
 public:
  // Creates the namespace and the pair; `tag` keeps concurrent runs apart (e.g. the pid).
  static Expected<NetnsLink> create(unsigned tag);
  NetnsLink(NetnsLink&& other) noexcept;
  NetnsLink& operator=(NetnsLink&&) = delete;
  ~NetnsLink();  // deletes the namespace (and with it the pair)

  const std::string& hostAddress() const { return host_ip_; }
  const std::string& namespaceAddress() const { return ns_ip_; }
  // The command prefix that runs a program inside the namespace.
  std::vector<std::string> prefix() const;
  // Drops every packet in and out of the namespace (true), or stops dropping (false).
  Status setDropping(bool drop);

 private:
  NetnsLink(std::string name, std::string host_ip, std::string ns_ip)
      : name_(std::move(name)), host_ip_(std::move(host_ip)), ns_ip_(std::move(ns_ip)) {}
  std::string name_;
  std::string host_ip_;
  std::string ns_ip_;
};

// Runs a program (searched on PATH) with its output discarded; an error naming the command when it
// cannot be started or does not exit 0.
Status runProgram(const std::vector<std::string>& argv);
// The program's full path on PATH (or /usr/sbin, /sbin), or empty.
std::string findProgram(const std::string& name);

}  // namespace fogmap::cli
