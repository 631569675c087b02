// edge-cluster: replays one sensor's scans, clusters them at the edge (MAD-C, baseline or ext) and
// pushes what the mode ships up the stream to its parent aggregator. Composition root only.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <set>
#include <string>
#include <thread>
#include <utility>

#include "common/topology.hpp"
#include "services/common/metrics.hpp"
#include "services/common/parent_link.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace {

using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

constexpr int kExitRuntimeError = 1;
constexpr int kExitBadConfig = 2;
constexpr std::uint64_t kStatusEveryFrames = 10;

// The one global: a signal handler can reach nothing else. Lock-free, so safe to set there.
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);

void requestStop(int /*signal*/) { g_stop.store(true); }

bool stopRequested() { return g_stop.load(); }

// Sleeps until `deadline` but wakes every 50 ms so that a stop request is honoured promptly.
void waitUntil(SteadyClock::time_point deadline) {
  while (!stopRequested()) {
    const SteadyClock::time_point now = SteadyClock::now();
    if (now >= deadline) return;
    std::this_thread::sleep_until(std::min(deadline, now + 50ms));
  }
}

std::int64_t wallClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void usage() { std::cerr << "usage: edge-cluster --topology FILE --node NAME\n"; }

struct Flags {
  std::filesystem::path topology;
  std::string node;
};

// "--name value" pairs only; anything else is a usage error.
bool parseFlags(int argc, char** argv, Flags& flags) {
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (i + 1 >= argc) return false;
    const std::string value = argv[++i];
    if (flag == "--topology") {
      flags.topology = value;
    } else if (flag == "--node") {
      flags.node = value;
    } else {
      return false;
    }
  }
  return !flags.topology.empty() && !flags.node.empty();
}

int badConfig(const std::string& message) {
  std::cerr << "edge-cluster: " << message << "\n";
  return kExitBadConfig;
}

// Queues everything the frame produced on the link; returns the number of uploads.
std::size_t ship(fogmap::EdgeOutput& output, fogmap::ParentLink& link) {
  std::size_t uploads = 0;
  if (output.map) {
    fogmap::v1::Upload upload;
    *upload.mutable_map() = fogmap::toProto(*output.map);
    link.send(std::move(upload));
    ++uploads;
  }
  for (const fogmap::PointChunk& chunk : output.chunks) {
    fogmap::v1::Upload upload;
    *upload.mutable_points() = fogmap::toProto(chunk);
    link.send(std::move(upload));
    ++uploads;
  }
  return uploads;
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

  fogmap::Expected<fogmap::ScanSource> source = fogmap::ScanSource::open(sensor);
  if (!source) return badConfig(source.error().message);

  const std::string host = node->host.empty() ? "127.0.0.1" : node->host;
  fogmap::Metrics metrics(host + ":" + std::to_string(node->metrics_port), "edge-cluster", node->name);
  const fogmap::EdgeNode edge(fogmap::edgeConfigFor(*topology, *node));

  fogmap::ParentLinkConfig link_config;
  link_config.target = parent->host + ":" + std::to_string(parent->port);
  link_config.max_message_bytes = topology->max_message_bytes;
  fogmap::ParentLinkHooks hooks;
  const std::string peer = parent->name;
  hooks.on_sent = [&metrics, peer](const std::string& kind, std::size_t bytes) { metrics.bytesSent(peer, kind, bytes); };
  hooks.on_reconnect = [&metrics] { metrics.reconnects(); };
  hooks.on_dropped = [&metrics] { metrics.droppedUploads(); };
  // Declared after `metrics`, so destroyed (and its thread stopped) before the hooks' target goes.
  fogmap::ParentLink link(link_config, std::move(hooks));

  std::cerr << "edge-cluster " << node->name << ": " << source->files().size() << " scan(s) from "
            << sensor.source.string() << " at " << sensor.rate_hz << " Hz, mode " << fogmap::modeName(topology->mode)
            << ", sending to " << parent->name << " (" << link_config.target << ")\n";

  // Epochs are windows of one sensor period on the wall clock (DESIGN 2.2): every edge captures
  // epoch k at k * period, so the sensors of one cluster report the same epoch at about the same
  // time (clocks are assumed synchronised, e.g. by NTP or PTP), and a replayed recording shows scan
  // k mod N in epoch k on every sensor.
  const auto period_ns = static_cast<std::int64_t>(1e9 / sensor.rate_hz);
  std::set<std::string> reported_bad_files;  // each bad file is named once, counted every time
  std::uint64_t frame_errors = 0;
  std::int64_t epoch = wallClockNs() / period_ns + 1;
  while (!stopRequested() && !source->done()) {
    waitUntil(SteadyClock::now() + std::chrono::nanoseconds(epoch * period_ns - wallClockNs()));
    if (stopRequested()) break;
    const auto this_epoch = static_cast<std::uint64_t>(epoch);
    // After a stall (slow disk, a frame longer than the period) skip to the next window instead
    // of bursting to catch up: a burst would stamp old data with new times.
    epoch = std::max(epoch + 1, wallClockNs() / period_ns + 1);

    fogmap::Expected<fogmap::ScanFrame> scan = source->at(this_epoch);
    // The sensor timestamp is when the scan is in memory, as a live sensor delivers it: reading and
    // cutting a recorded scan into a virtual LiDAR is the replay's cost, not the pipeline's.
    const std::int64_t sensor_time_ns = wallClockNs();
    if (!scan) {
      metrics.malformed("scan");
      if (reported_bad_files.insert(scan.error().message).second) {
        std::cerr << "edge-cluster " << node->name << ": skipping a scan: " << scan.error().message << "\n";
      }
      continue;
    }
    // Counted once per scan that had any: the reader already dropped them.
    if (scan->dropped_non_finite > 0) metrics.malformed("non_finite_points");

    fogmap::Expected<fogmap::EdgeOutput> output = edge.processFrame(scan->points, scan->sequence, sensor_time_ns);
    if (!output) {
      metrics.malformed("frame");
      if (frame_errors++ % kStatusEveryFrames == 0) {
        std::cerr << "edge-cluster " << node->name << ": frame " << scan->sequence << " (" << scan->file.string()
                  << ") failed (" << frame_errors << " so far): " << output.error().message << "\n";
      }
      continue;
    }

    metrics.framesProcessed();
    metrics.pointsIn(output->points_in);
    metrics.pointsOut(output->points_out);
    if (output->map) {
      metrics.clusteringSeconds(output->clustering_seconds);
      metrics.mapsOut();
    }
    const std::size_t uploads = ship(*output, link);

    if (scan->sequence % kStatusEveryFrames == 0) {
      std::cerr << "edge-cluster " << node->name << ": frame " << scan->sequence << ": " << output->points_in
                << " points in, " << output->points_out << " after pre-processing (" << output->preprocess_seconds * 1e3
                << " ms), " << output->clusters << " clusters (" << output->clustering_seconds * 1e3 << " ms), "
                << uploads << " upload(s); link "
                << (link.connected() ? "connected" : "disconnected") << ", " << link.unacknowledged()
                << " unacknowledged\n";
    }
  }

  if (stopRequested()) {
    const bool flushed = link.flush(1s);
    std::cerr << "edge-cluster " << node->name << ": stopping after " << source->emitted() << " frame(s)"
              << (flushed ? "" : "; " + std::to_string(link.unacknowledged()) + " upload(s) unacknowledged") << "\n";
    return 0;
  }
  if (source->emitted() == 0) {
    std::cerr << "edge-cluster " << node->name << ": no readable scan in " << sensor.source.string() << "\n";
    return kExitRuntimeError;
  }
  const bool flushed = link.flush(5s);
  std::cerr << "edge-cluster " << node->name << ": done after " << source->emitted() << " frame(s)"
            << (flushed ? ", all acknowledged" : "; " + std::to_string(link.unacknowledged()) + " upload(s) unacknowledged")
            << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 2 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    usage();
    return 0;
  }
  Flags flags;
  if (!parseFlags(argc, argv, flags)) {
    usage();
    return kExitBadConfig;
  }
  std::signal(SIGINT, requestStop);
  std::signal(SIGTERM, requestStop);
  try {
    return run(flags);
  } catch (const std::exception& e) {
    // Only the outside world throws here (e.g. the metrics port is taken).
    std::cerr << "edge-cluster: " << e.what() << "\n";
    return kExitRuntimeError;
  }
}
