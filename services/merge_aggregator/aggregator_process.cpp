#include "services/merge_aggregator/aggregator_process.hpp"

#include <map>
#include <string>
#include <utility>

namespace fogmap {

Expected<std::unique_ptr<AggregatorProcess>> AggregatorProcess::create(const ServiceContext& context) {
  auto config = aggregatorConfigFor(context.topology, context.node.name);
  if (!config) return config.error();
  auto core = MergeAggregator::create(std::move(*config));
  if (!core) return core.error();
  return std::unique_ptr<AggregatorProcess>(new AggregatorProcess(context, std::move(*core)));
}

AggregatorProcess::AggregatorProcess(const ServiceContext& context, MergeAggregator core)
    : context_(context),
      is_root_(core.config().is_root),
      aggregator_(std::move(core)),
      ingest_(aggregator_, &context.metrics,
              is_root_ ? Relay{} : Relay([this](v1::Upload upload, RelaySettled settled) {
                parent_link_->send(std::move(upload), std::move(settled));
              })),
      emitter_(aggregator_, emitterSinks(), &context.metrics) {
  const TopologyConfig& topology = context.topology;
  context.metrics.periodSeconds(topology.period_ms / 1000.0);
  if (is_root_) {
    global_maps_.emplace(aggregator_, &context.metrics);
    std::map<std::uint32_t, std::string> sensor_names;
    for (const NodeConfig& node : topology.nodes) {
      if (node.role == Role::kEdge) sensor_names[node.id] = node.name;
    }
    emitter_.sensorNames(std::move(sensor_names));
  } else {
    const NodeConfig& parent = *topology.find(context.node.parent);  // the topology's validation: it exists
    parent_link_ =
        std::make_unique<ParentLink>(context.linkTo<ParentLinkConfig>(parent), context.parentLinkHooks(parent));
  }
  ingest_.onArrival([this] { emitter_.wake(); });
  std::map<std::uint32_t, std::string> peer_names;
  for (const NodeConfig* child : topology.children(context.node.name)) peer_names[child->id] = child->name;
  ingest_.peerNames(std::move(peer_names));
  if (context.tls) {
    ingest_.identifyPeersByCertificate();
    if (global_maps_) global_maps_->allowGeofenceSetters(topology.tls->geofence_clients);
  }
}

EmitterSinks AggregatorProcess::emitterSinks() {
  // Called before the adapter or the link exist; the emitter calls its sinks only once it runs.
  EmitterSinks sinks;
  if (is_root_) {
    sinks.publish = [this](const GlobalMapMessage& message) { global_maps_->publish(message); };
  } else {
    sinks.to_parent = [this](v1::Upload upload) { parent_link_->send(std::move(upload)); };
    sinks.link_drops = [this] { return parent_link_->dropped(); };
  }
  return sinks;
}

std::vector<grpc::Service*> AggregatorProcess::services() {
  std::vector<grpc::Service*> out{&ingest_};
  if (global_maps_) out.push_back(&*global_maps_);
  return out;
}

ServiceLifecycle AggregatorProcess::lifecycle() {
  ServiceLifecycle steps;
  steps.serving = [this](int /*port*/) { emitter_.start(); };
  steps.stop_accepting = [this] { ingest_.stopAccepting(); };
  steps.drain = [this] {
    emitter_.stop();
    emitter_.drain();
  };
  if (is_root_) {
    steps.end_subscriptions = [this](std::chrono::milliseconds budget) { global_maps_->shutdown(budget); };
  } else {
    steps.flush = [this](std::chrono::milliseconds budget) {
      if (!parent_link_->flush(budget)) {
        context_.log(std::to_string(parent_link_->unacknowledged()) +
                     " upload(s) unanswered by the parent at shutdown");
      }
    };
  }
  return steps;
}

}  // namespace fogmap
