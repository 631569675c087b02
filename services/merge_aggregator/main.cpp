// merge-aggregator: the composition root. Reads the topology, builds the core, metrics, parent
// link, adapters and server, runs until SIGINT or SIGTERM.
//   merge-aggregator --topology FILE --node NAME
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <grpcpp/grpcpp.h>

#include "common/certs.hpp"
#include "common/topology.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/service_process.hpp"
#include "services/common/parent_link.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"
#include "services/merge_aggregator/global_map_service.hpp"
#include "services/merge_aggregator/ingest_service.hpp"

namespace {

using namespace std::chrono_literals;

constexpr int kBadConfig = 2;
constexpr int kRuntimeFailure = 1;

// Shutdown on SIGTERM or SIGINT is bounded (docs/design.md "Delivery"): from the signal to exit
// 0 at most kShutdownDeadline. The drain (emitting every open epoch) comes first; subscribers
// then get up to kSubscriberDrain to read what was published, open calls up to kCallGrace to end
// on their own before they are cancelled (children's streams end at their next upload; a call
// that arrives while the server stops may never reach a handler and ends only then), and an
// intermediate's parent whatever is left to answer its last uploads, but kTeardown, kept for the
// destructors (server, links, metrics endpoint).
constexpr auto kShutdownDeadline = 5s;
constexpr auto kSubscriberDrain = 500ms;
constexpr auto kCallGrace = 500ms;
constexpr auto kTeardown = 250ms;

struct Args {
  std::string topology;
  std::string node;
};

void usage(std::ostream& out) {
  out << "usage: merge-aggregator --topology FILE --node NAME\n";
}

std::optional<Args> parseArgs(int argc, char** argv) {
  if (fogmap::wantsHelp(argc, argv)) {
    usage(std::cout);
    std::exit(EXIT_SUCCESS);
  }
  const auto args = fogmap::parseServiceArgs(argc, argv);
  if (!args) {
    std::cerr << "merge-aggregator: --topology FILE and --node NAME are required, and nothing else\n";
    return std::nullopt;
  }
  return Args{args->topology, args->node};
}

int run(const Args& args, const sigset_t& stop_signals) {
  using namespace fogmap;
  const auto topology = loadTopology(args.topology);
  if (!topology) {
    std::cerr << "merge-aggregator: " << topology.error().message << "\n";  // names the file already
    return kBadConfig;
  }
  const NodeConfig* self = topology->find(args.node);
  if (self == nullptr || self->role != Role::kAggregator) {
    std::cerr << "merge-aggregator: " << args.topology << " has no aggregator named '" << args.node << "'\n";
    return kBadConfig;
  }

  // Read and checked before anything starts: a missing or wrong file is a configuration error.
  const auto tls = loadTls(*topology, self->name, std::chrono::system_clock::now());
  if (!tls) {
    std::cerr << "merge-aggregator " << self->name << ": tls: " << tls.error().message << "\n";
    return kBadConfig;
  }

  auto config = aggregatorConfigFor(*topology, self->name);
  if (!config) {
    std::cerr << "merge-aggregator: " << args.topology << ": " << config.error().message << "\n";
    return kBadConfig;
  }
  auto core = MergeAggregator::create(std::move(*config));
  if (!core) {
    std::cerr << "merge-aggregator: " << args.topology << ": " << core.error().message << "\n";
    return kBadConfig;
  }
  const bool is_root = core->config().is_root;
  SharedAggregator aggregator(std::move(*core));

  Metrics metrics(self->host + ":" + std::to_string(self->metrics_port), serviceName(Role::kAggregator), self->name);
  metrics.periodSeconds(topology->period_ms / 1000.0);

  std::unique_ptr<ParentLink> parent_link;
  if (!is_root) {
    const NodeConfig* parent = topology->find(self->parent);
    const std::string parent_name = parent->name;
    ParentLinkConfig link_config;
    link_config.target = parent->host + ":" + std::to_string(parent->port);
    link_config.credentials = channelCredentials(*tls);
    link_config.max_message_bytes = topology->max_message_bytes;
    ParentLinkHooks hooks;
    hooks.on_sent = [&metrics, parent_name](const std::string& kind, std::size_t bytes) {
      metrics.bytesSent(parent_name, kind, bytes);
    };
    hooks.on_reconnect = [&metrics] { metrics.reconnects(); };
    const std::string self_name = self->name;
    hooks.on_stalled = [&metrics, self_name](std::chrono::milliseconds waited) {
      metrics.linkStalls();
      std::cerr << "merge-aggregator " << self_name << ": the parent has owed an answer for " << waited.count()
                << " ms; re-opening the stream\n";
    };
    hooks.on_dropped = [&metrics, self_name](std::uint64_t total, bool first_of_burst) {
      metrics.droppedUploads();
      if (first_of_burst) {
        std::cerr << "merge-aggregator " << self_name << ": the send queue to the parent is full; dropping the oldest "
                  << "uploads (" << total << " dropped so far)\n";
      }
    };
    hooks.on_refused = [&metrics, self_name](std::uint64_t sequence, const std::string& reason) {
      metrics.uploadsRefused();
      std::cerr << "merge-aggregator " << self_name << ": the parent refused upload " << sequence << ": " << reason
                << "\n";
    };
    parent_link = std::make_unique<ParentLink>(std::move(link_config), std::move(hooks));
  }
  auto to_parent = [&parent_link](v1::Upload upload) { parent_link->send(std::move(upload)); };
  Relay relay;
  if (parent_link) {
    relay = [&parent_link](v1::Upload upload, RelaySettled settled) {
      parent_link->send(std::move(upload), std::move(settled));
    };
  }

  IngestService ingest(aggregator, &metrics, std::move(relay));
  std::optional<GlobalMapService> global_maps;
  EmitterSinks sinks;
  if (is_root) {
    global_maps.emplace(aggregator, &metrics);
    sinks.publish = [&global_maps](const GlobalMapMessage& message) { global_maps->publish(message); };
  } else {
    sinks.to_parent = to_parent;
    sinks.link_drops = [&parent_link] { return parent_link->dropped(); };
  }
  Emitter emitter(aggregator, std::move(sinks), &metrics);
  if (is_root) {
    std::map<std::uint32_t, std::string> sensor_names;
    for (const NodeConfig& node : topology->nodes) {
      if (node.role == Role::kEdge) sensor_names[node.id] = node.name;
    }
    emitter.sensorNames(std::move(sensor_names));
  }
  ingest.onArrival([&emitter] { emitter.wake(); });
  std::map<std::uint32_t, std::string> peer_names;
  for (const NodeConfig* child : topology->children(self->name)) peer_names[child->id] = child->name;
  ingest.peerNames(std::move(peer_names));
  if (*tls) {
    ingest.identifyPeersByCertificate();
    if (global_maps) global_maps->allowGeofenceSetters(topology->tls->geofence_clients);
  }

  grpc::ServerBuilder builder;
  configureServer(builder, topology->max_message_bytes);
  int bound_port = 0;
  const std::string address = self->host + ":" + std::to_string(self->port);
  builder.AddListeningPort(address, serverCredentials(*tls), &bound_port);
  builder.RegisterService(&ingest);
  if (global_maps) builder.RegisterService(&*global_maps);
  const std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || bound_port == 0) {
    std::cerr << "merge-aggregator: cannot listen on " << address << "\n";
    return kRuntimeFailure;
  }
  emitter.start();
  std::cerr << "ready" << std::endl;

  int signal = 0;
  sigwait(&stop_signals, &signal);
  const auto signalled = std::chrono::steady_clock::now();
  const auto left = [deadline = signalled + kShutdownDeadline - kTeardown] {
    const auto rest = deadline - std::chrono::steady_clock::now();
    return std::max(0ms, std::chrono::duration_cast<std::chrono::milliseconds>(rest));
  };

  // Nothing acknowledged is abandoned: stop taking uploads (unanswered ones are re-sent by the
  // children to the restarted node), emit every open epoch, let subscribers read what was
  // published, then end the server; an intermediate gives its last uploads time to be answered.
  ingest.stopAccepting();
  emitter.stop();
  emitter.drain();
  if (global_maps) global_maps->shutdown(std::min<std::chrono::milliseconds>(kSubscriberDrain, left()));
  server->Shutdown(std::chrono::system_clock::now() + std::min<std::chrono::milliseconds>(kCallGrace, left()));
  server->Wait();
  if (parent_link && !parent_link->flush(left())) {
    std::cerr << "merge-aggregator " << self->name << ": " << parent_link->unacknowledged()
              << " upload(s) unanswered by the parent at shutdown\n";
  }
  const auto took = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - signalled);
  std::cerr << "merge-aggregator " << self->name << ": stopped " << took.count() << " ms after the signal\n";
  return EXIT_SUCCESS;
}

}  // namespace

int main(int argc, char** argv) {
  // Blocked before any thread starts, so every thread inherits the mask and sigwait below is
  // the only place that sees the signals.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  const auto args = parseArgs(argc, argv);
  if (!args) {
    usage(std::cerr);
    return kBadConfig;
  }
  try {
    return run(*args, stop_signals);
  } catch (const std::exception& e) {
    // prometheus-cpp's exposer throws when its port is taken.
    std::cerr << "merge-aggregator: " << e.what() << "\n";
    return kRuntimeFailure;
  }
}
