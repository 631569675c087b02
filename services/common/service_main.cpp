#include "services/common/service_main.hpp"

#include <algorithm>
#include <exception>
#include <iostream>
#include <memory>

#include "common/config/topology_parse.hpp"

namespace fogmap {

void ServiceContext::serveMetrics() const { metrics.serve(endpoint(node.host, node.metrics_port)); }

std::string ServiceContext::prefix() const { return std::string(serviceName(spec.role)) + " " + node.name + ": "; }

// One write per line, so that lines of several threads never interleave.
void ServiceContext::log(const std::string& line) const { std::cerr << (prefix() + line + "\n"); }

int ServiceContext::badConfig(const std::string& message) const {
  std::cerr << serviceName(spec.role) << ": " << message << "\n";
  return kExitBadConfig;
}

std::optional<std::string> ServiceContext::flag(const std::string& name) const {
  const auto it = flags.find(name);
  if (it == flags.end()) return std::nullopt;
  return it->second;
}

ParentLinkHooks ServiceContext::parentLinkHooks(const NodeConfig& parent) const {
  ParentLinkHooks hooks;
  Metrics& counted = metrics;
  hooks.on_sent = [&counted, peer = parent.name](const std::string& kind, std::size_t bytes) {
    counted.bytesSent(peer, kind, bytes);
  };
  hooks.on_reconnect = [&counted] { counted.reconnects(); };
  // Each line one write, as log() does; by value, so that the hooks outlive this context's copy.
  const auto log = [prefix = prefix()](const std::string& line) { std::cerr << (prefix + line + "\n"); };
  hooks.on_stalled = [&counted, log](std::chrono::milliseconds waited) {
    counted.linkStalls();
    log("the parent has owed an answer for " + std::to_string(waited.count()) + " ms; re-opening the stream");
  };
  hooks.on_dropped = [&counted, log](std::uint64_t total, bool first_of_burst) {
    counted.droppedUploads();
    if (first_of_burst) {
      log("the send queue to the parent is full; dropping the oldest uploads (" + std::to_string(total) +
          " dropped so far)");
    }
  };
  hooks.on_refused = [&counted, log](std::uint64_t sequence, const std::string& reason) {
    counted.uploadsRefused();
    log("the parent refused upload " + std::to_string(sequence) + ": " + reason);
  };
  return hooks;
}

int runService(int argc, char** argv, const ServiceSpec& spec, const std::function<int(ServiceContext&)>& run) {
  StopRequest stop;
  StopSignals signals(stop);  // before any other thread starts, so that every one inherits the mask
  const std::string name = serviceName(spec.role);
  if (wantsHelp(argc, argv)) {
    std::cout << spec.usage;
    return 0;
  }
  const std::optional<ServiceArgs> args = parseServiceArgs(argc, argv, spec.extra_flags);
  if (!args) {
    std::cerr << name << ": --topology FILE and --node NAME are required, and no flag but those below\n" << spec.usage;
    return kExitBadConfig;
  }
  const std::filesystem::path topology_file = args->topology;
  const auto bad = [&name](const std::string& message) {
    std::cerr << name << ": " << message << "\n";
    return kExitBadConfig;
  };
  try {
    const Expected<TopologyConfig> topology = loadTopology(topology_file);
    if (!topology) return bad(topology.error().message);  // names the file already
    const NodeConfig* node = topology->find(args->node);
    if (node == nullptr) return bad("no node '" + args->node + "' in " + topology_file.string());
    if (node->role != spec.role) {
      return bad(topology_file.string() + " has no " + roleName(spec.role) + " named '" + args->node + "' (it is " +
                 roleName(node->role) + ")");
    }
    // Read and checked before anything starts: a missing or wrong file is a configuration error.
    const auto tls = loadTls(*topology, node->name, std::chrono::system_clock::now());
    if (!tls) {
      std::cerr << name << " " << node->name << ": tls: " << tls.error().message << "\n";
      return kExitBadConfig;
    }
    Metrics metrics("", name, node->name);
    ServiceContext context{spec, topology_file, *topology, *node, *tls, args->extra, stop, metrics};
    return run(context);
  } catch (const std::exception& e) {
    // Only the outside world throws here (prometheus-cpp's exposer when its port is taken).
    std::cerr << name << ": " << e.what() << "\n";
    return kExitRuntimeError;
  }
}

int serveUntilStopped(const ServiceContext& context, const std::vector<grpc::Service*>& services,
                      const ServiceLifecycle& lifecycle, const ShutdownBudget& budget) {
  grpc::ServerBuilder builder;
  configureServer(builder, context.topology.max_message_bytes);
  int port = 0;
  const std::string address = endpoint(context.node.host, context.node.port);
  builder.AddListeningPort(address, serverCredentials(context.tls), &port);
  for (grpc::Service* service : services) builder.RegisterService(service);
  const std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::cerr << serviceName(context.spec.role) << ": cannot listen on " << address << "\n";
    return kExitRuntimeError;
  }
  if (lifecycle.serving) lifecycle.serving(port);
  std::cerr << "ready" << std::endl;

  context.stop.wait();
  const auto signalled = context.stop.requestedAt().value_or(std::chrono::steady_clock::now());
  const auto left = [deadline = signalled + budget.deadline - budget.teardown] {
    const auto rest = deadline - std::chrono::steady_clock::now();
    return std::max(std::chrono::milliseconds(0), std::chrono::duration_cast<std::chrono::milliseconds>(rest));
  };
  // Nothing acknowledged is abandoned: take nothing new in (what was not answered is re-sent by its
  // sender to the restarted node), finish and publish what was taken in, let subscribers read it,
  // then end the server; what the links still hold gets the rest of the deadline.
  if (lifecycle.stop_accepting) lifecycle.stop_accepting();
  if (lifecycle.drain) lifecycle.drain();
  if (lifecycle.end_subscriptions) lifecycle.end_subscriptions(std::min(budget.subscriber_drain, left()));
  server->Shutdown(std::chrono::system_clock::now() + std::min(budget.call_grace, left()));
  server->Wait();
  if (lifecycle.flush) lifecycle.flush(left());
  const auto took = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - signalled);
  context.log("stopped " + std::to_string(took.count()) + " ms after the signal");
  return 0;
}

}  // namespace fogmap
