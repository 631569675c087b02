#pragma once
// The one way a fogmap service process starts and stops; each service's main.cpp only composes
// its own parts between the two.
//
// Start-up (runService): SIGINT and SIGTERM blocked and taken by one waiter thread (StopSignals)
// before any other thread starts; --help; the command line (--topology FILE --node NAME and the
// service's own flags); the topology loaded and the node found in the service's role; its TLS files
// read and checked; /metrics served on the node's metrics address. Any of these failing is one line
// on stderr and exit code 2 (a port taken: 1).
//
// A gRPC service then serves until the stop request (serveUntilStopped) and stops in one order:
// stop accepting, drain what was taken in, let subscribers read what is queued, end the open calls,
// flush the links, exit 0; all of it within ShutdownBudget::deadline of the signal.
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/certs/certs.hpp"
#include "common/config/topology.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/parent_link.hpp"
#include "services/common/service_process.hpp"

namespace fogmap {

inline constexpr int kExitRuntimeError = 1;
inline constexpr int kExitBadConfig = 2;

struct ServiceSpec {
  Role role;          // the role of the nodes it runs; serviceName(role) names the binary and its lines
  std::string usage;  // what --help prints (and a wrong command line, after the error)
  std::set<std::string> extra_flags = {};  // its own "--name value" flags besides --topology and --node
};

// What start-up read and checked, for the service's own composition. Everything outlives run().
struct ServiceContext {
  const ServiceSpec& spec;
  const std::filesystem::path& topology_file;
  const TopologyConfig& topology;
  const NodeConfig& node;            // the node this process runs, in `topology`
  const std::optional<TlsPem>& tls;  // its identity; std::nullopt: plaintext
  const std::map<std::string, std::string>& flags;  // the extra flags given, names without "--"
  StopRequest& stop;
  Metrics& metrics;  // served on the node's metrics_port once serveMetrics() is called

  // Opens /metrics on the node's metrics address: each main calls it once its own parts are built
  // and checked, so a service refused by its configuration never shows a live port. Throws
  // std::runtime_error when the port is taken (runService reports it).
  void serveMetrics() const;

  // "<service> <node>: ", leading every line the process writes once it runs.
  std::string prefix() const;
  // Writes prefix() + line to stderr.
  void log(const std::string& line) const;
  // Writes "<service>: message" to stderr; returns kExitBadConfig.
  int badConfig(const std::string& message) const;
  // The value of an extra flag, std::nullopt when not given.
  std::optional<std::string> flag(const std::string& name) const;
  // A link's settings to `peer`: its gRPC endpoint, this node's credentials, the topology's
  // message limit (ParentLinkConfig, TrackerLinkConfig).
  template <class LinkConfig>
  LinkConfig linkTo(const NodeConfig& peer) const {
    LinkConfig config;
    config.target = endpoint(peer.host, peer.port);
    config.credentials = channelCredentials(tls);
    config.max_message_bytes = topology.max_message_bytes;
    return config;
  }
  // An upload link's observers: what it sends, its reconnects, stalls, drops and refusals counted in
  // `metrics` (peer label: `parent`'s name); stalls, refusals and the first drop of a burst logged.
  ParentLinkHooks parentLinkHooks(const NodeConfig& parent) const;
};

// Starts the process as above and returns run(context)'s exit code; an exception (the outside
// world: a port taken) is one line and kExitRuntimeError. Call it first thing in main.
int runService(int argc, char** argv, const ServiceSpec& spec, const std::function<int(ServiceContext&)>& run);

// The bounds of a gRPC service's shutdown (docs/design.md "Delivery"), from the stop request.
struct ShutdownBudget {
  std::chrono::milliseconds deadline{5000};          // to the exit
  std::chrono::milliseconds subscriber_drain{500};   // subscribers reading what is queued for them
  std::chrono::milliseconds call_grace{500};         // open calls ending on their own before they are cancelled
  std::chrono::milliseconds teardown{250};           // kept for the destructors (server, links, metrics endpoint)
};

// A gRPC service's parts of its life, in the order serveUntilStopped calls them; each may be empty.
struct ServiceLifecycle {
  std::function<void(int port)> serving;  // the server is up on `port`: start the threads that feed it
  // After the stop request:
  std::function<void()> stop_accepting;   // 1. take nothing new in (uploads, frames, ticks)
  std::function<void()> drain;            // 2. finish what was taken in and publish it (open epochs)
  // 3. let subscribers read what is queued for them, within `budget`, then end their streams
  std::function<void(std::chrono::milliseconds budget)> end_subscriptions;
  // 4. (serveUntilStopped: the server stops; open calls get the call grace, then are cancelled)
  // 5. give the links (and logs) what is left of the deadline
  std::function<void(std::chrono::milliseconds budget)> flush;
};

// Serves `services` on the node's endpoint with its credentials, says "ready" on stderr once
// `lifecycle.serving` returned, waits for the stop request, stops as `lifecycle` says within
// `budget`, and returns 0; kExitRuntimeError when the address cannot be bound.
int serveUntilStopped(const ServiceContext& context, const std::vector<grpc::Service*>& services,
                      const ServiceLifecycle& lifecycle, const ShutdownBudget& budget = {});

}  // namespace fogmap
