// edge-cluster: replays one sensor's scans, clusters them at the edge (MAD-C, baseline or ext) and
// pushes what the mode ships up the stream to its parent aggregator; with a displacement section,
// also streams each scan's displacement centroids to its tracker. Composition root only: the
// replay loop and its policy are EdgeRunner's, the centroids EdgeNode's.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "common/certs.hpp"
#include "common/clock.hpp"
#include "common/epochs.hpp"
#include "common/topology.hpp"
#include "services/common/delivery_journal.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/service_process.hpp"
#include "services/common/parent_link.hpp"
#include "services/common/proto_convert.hpp"
#include "services/common/tracker_link.hpp"
#include "services/edge_cluster/edge_metrics.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/edge_runner.hpp"
#include "services/edge_cluster/scan_source.hpp"
#include "services/edge_cluster/sim_scan_source.hpp"

namespace {

using namespace std::chrono_literals;

constexpr int kExitRuntimeError = 1;
constexpr int kExitBadConfig = 2;
// Shutdown on SIGTERM or SIGINT (docs/design.md "Delivery"): the wait for the next epoch sees the
// request within kStopPollNs, a frame in progress is finished and shipped, and the uploads not yet
// answered get kStopFlush to be answered before the edge exits 0 (what is still unanswered then
// goes with the process). At the end of the recording the last uploads get kDoneFlush.
constexpr std::int64_t kStopPollNs = 50'000'000;
constexpr auto kStopFlush = 1s;
constexpr auto kDoneFlush = 5s;

using fogmap::stopRequested;

bool waitUntil(std::int64_t until_ns) { return fogmap::sleepUntilUnlessStopped(until_ns, kStopPollNs); }

void usage() {
  std::cerr << "usage: edge-cluster --topology FILE --node NAME [--journal FILE]\n"
               "  --journal FILE  record how each upload ended (fault tests compare it with the root's maps)\n";
}

struct Flags {
  std::filesystem::path topology;
  std::string node;
  std::filesystem::path journal;  // empty: none
};

int badConfig(const std::string& message) {
  std::cerr << "edge-cluster: " << message << "\n";
  return kExitBadConfig;
}

// Queues everything an epoch produced on the links (the centroids, when there are any, on the
// tracker's); with a journal, records how each upload ends.
void ship(const fogmap::EdgeOutput& output, fogmap::ParentLink& link, fogmap::DeliveryJournal* journal,
          fogmap::CentroidLink* centroid_link) {
  if (output.centroids && centroid_link != nullptr) centroid_link->send(*output.centroids);
  const auto settled = [journal](std::uint64_t epoch, const char* kind) -> fogmap::ParentLink::Settled {
    if (journal == nullptr) return {};
    return [journal, epoch, kind](const std::optional<fogmap::v1::Ack>& answer) {
      journal->record({epoch, kind, fogmap::outcomeOf(answer)});
    };
  };
  if (output.map) {
    fogmap::v1::Upload upload;
    *upload.mutable_map() = fogmap::toProto(*output.map);
    link.send(std::move(upload), settled(output.map->header.epoch, "map"));
  }
  for (const fogmap::PointChunk& chunk : output.chunks) {
    fogmap::v1::Upload upload;
    *upload.mutable_points() = fogmap::toProto(chunk);
    link.send(std::move(upload), settled(chunk.header.epoch, "points"));
  }
}

int run(const Flags& flags) {
  fogmap::Expected<fogmap::TopologyConfig> topology = fogmap::loadTopology(flags.topology);
  if (!topology) return badConfig(topology.error().message);
  const fogmap::NodeConfig* node = topology->find(flags.node);
  if (node == nullptr) return badConfig("no node '" + flags.node + "' in " + flags.topology.string());
  if (node->role != fogmap::Role::kEdge || !node->sensor) {
    return badConfig("node '" + flags.node + "' is not an edge with a sensor in " + flags.topology.string());
  }
  const fogmap::NodeConfig* parent = node->parent.empty() ? nullptr : topology->find(node->parent);
  if (parent == nullptr) return badConfig("edge '" + flags.node + "' has no parent aggregator to send to");
  const fogmap::SensorConfig& sensor = *node->sensor;
  if (!(sensor.rate_hz > 0.0)) return badConfig("edge '" + flags.node + "': rate_hz must be positive");
  fogmap::Expected<fogmap::EpochSchedule> schedule =
      fogmap::EpochSchedule::create(topology->period_ms, topology->deadline_ms);
  if (!schedule) return badConfig(flags.topology.string() + ": " + schedule.error().message);

  fogmap::Expected<std::unique_ptr<fogmap::ScanProvider>> source =
      fogmap::openScanProvider(sensor, fogmap::ReadLimits{topology->max_scan_bytes});
  if (!source) return badConfig(source.error().message);
  fogmap::ScanProvider& scans = **source;
  if (const fogmap::Status pose = fogmap::checkSensorPose(sensor); !pose) {
    return badConfig("node '" + node->name + "': " + pose.error().message);
  }

  std::optional<fogmap::DeliveryJournal> journal;
  if (!flags.journal.empty()) {
    auto opened = fogmap::DeliveryJournal::open(flags.journal);
    if (!opened) return badConfig(opened.error().message);
    journal.emplace(std::move(*opened));
  }
  // Read and checked before anything starts: a missing or wrong file is a configuration error.
  const auto tls = fogmap::loadTls(*topology, node->name, std::chrono::system_clock::now());
  if (!tls) return badConfig("tls: " + tls.error().message);

  const std::string host = node->host.empty() ? "127.0.0.1" : node->host;
  fogmap::Metrics metrics(host + ":" + std::to_string(node->metrics_port), fogmap::serviceName(fogmap::Role::kEdge), node->name);
  metrics.periodSeconds(topology->period_ms / 1000.0);
  const std::string prefix = "edge-cluster " + node->name + ": ";

  fogmap::ParentLinkConfig link_config;
  link_config.target = parent->host + ":" + std::to_string(parent->port);
  link_config.credentials = fogmap::channelCredentials(*tls);
  link_config.max_message_bytes = topology->max_message_bytes;
  fogmap::ParentLinkHooks hooks;
  const std::string peer = parent->name;
  hooks.on_sent = [&metrics, peer](const std::string& kind, std::size_t bytes) { metrics.bytesSent(peer, kind, bytes); };
  hooks.on_reconnect = [&metrics] { metrics.reconnects(); };
  hooks.on_stalled = [&metrics, prefix](std::chrono::milliseconds waited) {
    metrics.linkStalls();
    std::cerr << prefix << "the parent has owed an answer for " << waited.count() << " ms; re-opening the stream\n";
  };
  hooks.on_dropped = [&metrics, prefix](std::uint64_t total, bool first_of_burst) {
    metrics.droppedUploads();
    if (first_of_burst) {
      std::cerr << prefix << "the send queue to the parent is full; dropping the oldest uploads (" << total
                << " dropped so far)\n";
    }
  };
  hooks.on_refused = [&metrics, prefix](std::uint64_t sequence, const std::string& reason) {
    metrics.uploadsRefused();
    std::cerr << prefix << "the parent refused upload " << sequence << ": " << reason << "\n";
  };
  // Declared after `metrics`, so destroyed (and its thread stopped) before the hooks' target goes.
  fogmap::ParentLink link(link_config, std::move(hooks));

  const fogmap::EdgeConfig edge_config = fogmap::edgeConfigFor(*topology, *node);
  fogmap::MetricsObserver observer(metrics, edge_config.max_points_per_chunk, node->name);
  // Declared after the observer, so destroyed (and its thread stopped) before the hooks' target goes.
  std::optional<fogmap::CentroidLink> centroid_link;
  const fogmap::NodeConfig* tracker = node->displacement ? topology->find(node->displacement->tracker) : nullptr;
  if (tracker != nullptr) {  // the topology's validation: the tracker exists and takes centroids
    fogmap::TrackerLinkConfig centroid_config;
    centroid_config.target = tracker->host + ":" + std::to_string(tracker->port);
    centroid_config.credentials = fogmap::channelCredentials(*tls);
    centroid_config.max_message_bytes = topology->max_message_bytes;
    fogmap::TrackerLinkHooks centroid_hooks;
    centroid_hooks.on_sent = [&observer, peer = tracker->name](std::size_t bytes) { observer.centroidFrameSent(peer, bytes); };
    centroid_hooks.on_reconnect = [&metrics] { metrics.reconnects(); };
    centroid_hooks.on_dropped = [&observer, prefix](std::uint64_t total, bool first_of_burst) {
      observer.centroidFrameDropped();
      if (first_of_burst) {
        std::cerr << prefix << "the tracker is not taking centroids; dropping the oldest frames (" << total
                  << " dropped so far)\n";
      }
    };
    centroid_hooks.on_stream_ended = [prefix](const std::string& why) { std::cerr << prefix << "centroids: " << why << "\n"; };
    centroid_link.emplace(centroid_config, std::move(centroid_hooks));
  }
  fogmap::EdgeRunnerHooks runner_hooks;
  runner_hooks.now = fogmap::systemNowNs;
  runner_hooks.wait_until = waitUntil;
  runner_hooks.ship = [&link, &journal, &centroid_link](const fogmap::EdgeOutput& output) {
    ship(output, link, journal ? &*journal : nullptr, centroid_link ? &*centroid_link : nullptr);
  };
  runner_hooks.dropped_uploads = [&link] { return link.dropped(); };
  runner_hooks.log = [&prefix](const std::string& line) { std::cerr << prefix << line << "\n"; };
  runner_hooks.link_status = [&link] {
    return std::string("link ") + (link.connected() ? "connected" : "disconnected") + ", " +
           std::to_string(link.unacknowledged()) + " unacknowledged";
  };
  runner_hooks.observer = &observer;
  fogmap::EdgeRunner runner(fogmap::EdgeNode(edge_config), scans, *schedule,
                            sensor.rate_hz, std::move(runner_hooks));

  std::cerr << prefix << scans.describe() << " at "
            << sensor.rate_hz << " Hz, epochs of " << topology->period_ms << " ms, mode "
            << fogmap::modeName(topology->mode) << ", sending to " << parent->name << " (" << link_config.target
            << (*tls ? ", mutual TLS" : "") << ")"
            << (tracker != nullptr ? ", displacement centroids to " + tracker->name : std::string()) << "\n";

  runner.run();
  const fogmap::EdgeRunnerStats& stats = runner.stats();
  const std::string frames = std::to_string(stats.epochs_shipped) + " epoch(s) from " +
                             std::to_string(stats.scans_processed) + " scan(s), " +
                             std::to_string(stats.failed_frames) + " failed";
  // Centroids are perishable: whatever the tracker has not taken within a moment is abandoned.
  if (centroid_link) (void)centroid_link->flush(kStopFlush);
  if (stopRequested()) {
    const bool flushed = link.flush(kStopFlush);
    std::cerr << prefix << "stopping after " << frames
              << (flushed ? "" : "; " + std::to_string(link.unacknowledged()) + " upload(s) unacknowledged") << "\n";
    return 0;
  }
  if (scans.emitted() == 0) {
    std::cerr << prefix << "no readable scan (" << scans.describe() << ")\n";
    return kExitRuntimeError;
  }
  const bool flushed = link.flush(kDoneFlush);
  std::cerr << prefix << "done after " << frames
            << (flushed ? ", all acknowledged" : "; " + std::to_string(link.unacknowledged()) + " upload(s) unacknowledged")
            << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (fogmap::wantsHelp(argc, argv)) {
    usage();
    return 0;
  }
  const auto args = fogmap::parseServiceArgs(argc, argv, {"journal"});
  if (!args) {
    usage();
    return kExitBadConfig;
  }
  Flags flags;
  flags.topology = args->topology;
  flags.node = args->node;
  if (const auto journal = args->extra.find("journal"); journal != args->extra.end()) flags.journal = journal->second;
  fogmap::installStopFlag();
  try {
    return run(flags);
  } catch (const std::exception& e) {
    // Only the outside world throws here (e.g. the metrics port is taken).
    std::cerr << "edge-cluster: " << e.what() << "\n";
    return kExitRuntimeError;
  }
}
