#include "services/edge_cluster/edge_process.hpp"

#include <sstream>
#include <utility>

#include "common/base/clock.hpp"
#include "common/config/displacement_node.hpp"
#include "services/common/delivery_journal.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/sim_scan_source.hpp"

namespace fogmap {

Expected<std::unique_ptr<EdgeProcess>> EdgeProcess::create(const ServiceContext& context) {
  const TopologyConfig& topology = context.topology;
  const NodeConfig& node = context.node;
  const std::string file = context.topology_file.string();
  if (!node.sensor) return invalidArgument("node '" + node.name + "' is not an edge with a sensor in " + file);
  const NodeConfig* parent = node.parent.empty() ? nullptr : topology.find(node.parent);
  if (parent == nullptr) return invalidArgument("edge '" + node.name + "' has no parent aggregator to send to");
  const SensorConfig& sensor = *node.sensor;
  if (!(sensor.rate_hz > 0.0)) return invalidArgument("edge '" + node.name + "': rate_hz must be positive");
  Expected<EpochSchedule> schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return invalidArgument(file + ": " + schedule.error().message);
  Expected<std::unique_ptr<ScanProvider>> scans = openScanProvider(sensor, ReadLimits{topology.max_scan_bytes});
  if (!scans) return scans.error();
  if (const Status pose = checkSensorPose(sensor); !pose) {
    return invalidArgument("node '" + node.name + "': " + pose.error().message);
  }
  std::unique_ptr<DeliveryJournal> journal;
  if (const auto path = context.flag("journal")) {
    auto opened = DeliveryJournal::open(*path);
    if (!opened) return opened.error();
    journal = std::make_unique<DeliveryJournal>(std::move(*opened));
  }
  // A missing or corrupt model stops the edge here, before it ships anything.
  EdgeConfig edge_config = edgeConfigFor(topology, node);
  auto classifier = loadClassifierOf(topology);
  if (!classifier) return invalidArgument("edge '" + node.name + "': " + classifier.error().message);
  edge_config.classifier = std::move(*classifier);
  return std::unique_ptr<EdgeProcess>(new EdgeProcess(context, *parent, std::move(edge_config), std::move(*schedule),
                                                      std::move(*scans), std::move(journal)));
}

EdgeProcess::EdgeProcess(const ServiceContext& context, const NodeConfig& parent, EdgeConfig edge_config,
                         EpochSchedule schedule,
                         std::unique_ptr<ScanProvider> scans, std::unique_ptr<DeliveryJournal> journal)
    : context_(context),
      parent_(parent),
      // The topology's validation: a displacement section's tracker exists and takes centroids.
      tracker_(context.node.displacement ? context.topology.find(context.node.displacement->tracker) : nullptr),
      scans_(std::move(scans)),
      journal_(std::move(journal)),
      edge_config_(std::move(edge_config)),
      link_(context.linkTo<ParentLinkConfig>(parent), context.parentLinkHooks(parent)),
      observer_(context.metrics, edge_config_.max_points_per_chunk, context.node.name),
      runner_(EdgeNode(edge_config_), *scans_, schedule, context.node.sensor->rate_hz, runnerHooks()) {
  context.metrics.periodSeconds(context.topology.period_ms / 1000.0);
  if (tracker_ != nullptr) centroid_link_.emplace(context.linkTo<TrackerLinkConfig>(*tracker_), centroidLinkHooks());
}

EdgeProcess::~EdgeProcess() = default;

EdgeRunnerHooks EdgeProcess::runnerHooks() {
  // Called before the links exist: the runner calls its hooks only once it runs.
  EdgeRunnerHooks hooks;
  hooks.now = systemNowNs;
  hooks.wait_until = [this](std::int64_t until_ns) { return context_.stop.sleepUntil(until_ns, kStopPoll); };
  hooks.ship = [this](const EdgeOutput& output) { ship(output); };
  hooks.dropped_uploads = [this] { return link_.dropped(); };
  hooks.log = [this](const std::string& line) { context_.log(line); };
  hooks.link_status = [this] {
    return std::string("link ") + (link_.connected() ? "connected" : "disconnected") + ", " +
           std::to_string(link_.unacknowledged()) + " unacknowledged";
  };
  hooks.observer = &observer_;
  return hooks;
}

TrackerLinkHooks EdgeProcess::centroidLinkHooks() {
  TrackerLinkHooks hooks;
  hooks.on_sent = [this, peer = tracker_->name](std::size_t bytes) { observer_.centroidFrameSent(peer, bytes); };
  hooks.on_reconnect = [this] { context_.metrics.reconnects(); };
  hooks.on_dropped = [this](std::uint64_t total, bool first_of_burst) {
    observer_.centroidFrameDropped();
    if (first_of_burst) {
      context_.log("the tracker is not taking centroids; dropping the oldest frames (" + std::to_string(total) +
                   " dropped so far)");
    }
  };
  hooks.on_stream_ended = [this](const std::string& why) { context_.log("centroids: " + why); };
  return hooks;
}

void EdgeProcess::ship(const EdgeOutput& output) {
  if (output.centroids && centroid_link_) centroid_link_->send(*output.centroids);
  DeliveryJournal* journal = journal_.get();
  const auto settled = [journal](std::uint64_t epoch, const char* kind) -> ParentLink::Settled {
    if (journal == nullptr) return {};
    return [journal, epoch, kind](const std::optional<v1::Ack>& answer) {
      journal->record({epoch, kind, outcomeOf(answer)});
    };
  };
  if (output.map) {
    v1::Upload upload;
    *upload.mutable_map() = toProto(*output.map);
    link_.send(std::move(upload), settled(output.map->header.epoch, "map"));
  }
  for (const PointChunk& chunk : output.chunks) {
    v1::Upload upload;
    *upload.mutable_points() = toProto(chunk);
    link_.send(std::move(upload), settled(chunk.header.epoch, "points"));
  }
}

int EdgeProcess::run() {
  const TopologyConfig& topology = context_.topology;
  const SensorConfig& sensor = *context_.node.sensor;
  std::ostringstream started;
  started << scans_->describe() << " at " << sensor.rate_hz << " Hz, epochs of " << topology.period_ms << " ms, mode "
          << modeName(topology.mode) << ", sending to " << parent_.name << " (" << endpoint(parent_.host, parent_.port)
          << (context_.tls ? ", mutual TLS" : "") << ")"
          << (tracker_ != nullptr ? ", displacement centroids to " + tracker_->name : std::string());
  context_.log(started.str());
  runner_.run();
  const EdgeRunnerStats& stats = runner_.stats();
  const std::string frames = std::to_string(stats.epochs_shipped) + " epoch(s) from " +
                             std::to_string(stats.scans_processed) + " scan(s), " +
                             std::to_string(stats.failed_frames) + " failed";
  // Centroids are perishable: whatever the tracker has not taken within a moment is abandoned.
  if (centroid_link_) (void)centroid_link_->flush(kStopFlush);
  if (context_.stop.requested()) {
    const bool flushed = link_.flush(kStopFlush);
    context_.log("stopping after " + frames +
                 (flushed ? "" : "; " + std::to_string(link_.unacknowledged()) + " upload(s) unacknowledged"));
    return 0;
  }
  if (scans_->emitted() == 0) {
    context_.log("no readable scan (" + scans_->describe() + ")");
    return kExitRuntimeError;
  }
  const bool flushed = link_.flush(kDoneFlush);
  context_.log("done after " + frames +
               (flushed ? ", all acknowledged"
                        : "; " + std::to_string(link_.unacknowledged()) + " upload(s) unacknowledged"));
  return 0;
}

}  // namespace fogmap
