// tracker: the composition root. Reads the topology, builds the tracker core, its adapter, its
// LiDAR input (the feed of the root's global maps, or the collector of its edges' centroids) and
// the metrics, and runs until SIGINT or SIGTERM.
//   tracker --topology FILE --node NAME
#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/burst_log.hpp"
#include "common/certs.hpp"
#include "common/epochs.hpp"
#include "common/topology.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/service_process.hpp"
#include "services/tracker/centroid_collector.hpp"
#include "services/tracker/global_map_feed.hpp"
#include "services/tracker/tracker_hooks.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"
#include "services/tracker/tracker_service.hpp"

namespace {

using namespace std::chrono_literals;

constexpr int kBadConfig = 2;
constexpr int kRuntimeFailure = 1;
constexpr auto kSubscriberDrain = 500ms;
constexpr auto kCallGrace = 500ms;
constexpr auto kTick = 10ms;
constexpr std::size_t kSubscriberQueue = 16;  // track lists a subscriber may lag behind
constexpr auto kSubscriberPoll = 100ms;

struct Args {
  std::string topology;
  std::string node;
};

void usage(std::ostream& out) {
  out << "usage: tracker --topology FILE --node NAME\n"
         "Fuses the root's global maps (input: global_map) or the displacement centroids its edges stream\n"
         "(input: centroids; the edges whose displacement: section names it) with the detections of the\n"
         "tracker's cameras (the detection nodes whose parent it is) into tracks, served on\n"
         "TrackerService.Subscribe; settings in the node's tracker: section (input, centroid_merge_m,\n"
         "association paper|kalman, eps_sync_s, thresholds, track life cycle).\n";
}

std::optional<Args> parseArgs(int argc, char** argv) {
  if (fogmap::wantsHelp(argc, argv)) {
    usage(std::cout);
    std::exit(EXIT_SUCCESS);
  }
  const auto args = fogmap::parseServiceArgs(argc, argv);
  if (!args) {
    std::cerr << "tracker: --topology FILE and --node NAME are required, and nothing else\n";
    return std::nullopt;
  }
  return Args{args->topology, args->node};
}

int run(const Args& args, const sigset_t& stop_signals) {
  using namespace fogmap;
  const auto topology = loadTopology(args.topology);
  if (!topology) {
    std::cerr << "tracker: " << topology.error().message << "\n";
    return kBadConfig;
  }
  const NodeConfig* self = topology->find(args.node);
  if (self == nullptr || self->role != Role::kTracker) {
    std::cerr << "tracker: " << args.topology << " has no tracker named '" << args.node << "'\n";
    return kBadConfig;
  }
  const auto tls = loadTls(*topology, self->name, std::chrono::system_clock::now());
  if (!tls) {
    std::cerr << "tracker " << self->name << ": tls: " << tls.error().message << "\n";
    return kBadConfig;
  }
  std::vector<camera::PinholeCamera> cameras;
  std::vector<std::string> camera_names;
  for (const NodeConfig* c : topology->camerasOf(self->name)) {
    cameras.push_back(c->camera->calibration);
    camera_names.push_back(c->name);
  }
  auto tracker = tracking::Tracker::create(self->tracker->tracking, cameras);
  if (!tracker) {
    std::cerr << "tracker " << self->name << ": " << tracker.error().message << "\n";
    return kBadConfig;
  }

  Metrics metrics(self->host + ":" + std::to_string(self->metrics_port), serviceName(Role::kTracker), self->name);
  metrics.periodSeconds(topology->period_ms / 1000.0);
  const bool centroid_input = self->tracker->input == TrackerInput::kCentroids;
  std::vector<std::string> edge_names;
  for (const NodeConfig* e : topology->centroidEdgesOf(self->name)) edge_names.push_back(e->name);
  TrackerMetrics tracker_metrics(metrics, self->name, camera_names, edge_names);
  std::optional<CentroidCollector> collector;
  if (centroid_input) {
    const auto schedule = EpochSchedule::create(topology->period_ms, topology->deadline_ms);
    if (!schedule) {
      std::cerr << "tracker " << self->name << ": " << schedule.error().message << "\n";
      return kBadConfig;
    }
    collector.emplace(centroidCollectorConfigFor(*topology, *self), *schedule);
  }

  std::unique_ptr<TrackerService> service;
  TrackerNode node(
      std::move(*tracker), topology->madc.alpha, systemNowNs,
      [&service, &tracker_metrics](const TrackSnapshot& snapshot, const FusionReport& report) {
        tracker_metrics.fused(report);
        service->publish(snapshot);
      },
      std::move(collector), trackerNodeLimitsFor(*topology));
  BurstLog refusal_log(
      "tracker " + self->name + ": ", [](const std::string& line) { std::cerr << line << "\n"; }, systemNowNs);
  service = std::make_unique<TrackerService>(node, camera_names, tls->has_value(),
                                             trackerServiceHooks(metrics, tracker_metrics, refusal_log), kSubscriberQueue,
                                             kSubscriberPoll, topology->admission.max_subscribers);

  grpc::ServerBuilder builder;
  configureServer(builder, topology->max_message_bytes);
  int bound_port = 0;
  const std::string address = self->host + ":" + std::to_string(self->port);
  builder.AddListeningPort(address, serverCredentials(*tls), &bound_port);
  builder.RegisterService(service.get());
  const std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || bound_port == 0) {
    std::cerr << "tracker: cannot listen on " << address << "\n";
    return kRuntimeFailure;
  }

  // Input global_map: the root's maps; input centroids: the edges' streams reach the service.
  std::optional<GlobalMapFeed> feed;
  if (!centroid_input) {
    const NodeConfig* root = topology->root();
    feed.emplace(makeChannel(root->host + ":" + std::to_string(root->port), channelCredentials(*tls), topology->max_message_bytes),
                 globalMapFeedHooks(metrics, tracker_metrics, node, refusal_log, root->name));
  }
  // LiDAR frames waiting for late detections are fused when their wait ends, and epochs of
  // centroids at their deadline, even if nothing else arrives (a camera or an edge that stopped);
  // the cameras' staleness moves and quiet bursts of refusals are summarised.
  std::atomic<bool> stopping{false};
  std::thread ticker([&] {
    while (!stopping.load()) {
      tracker_metrics.cameraStaleness(node.tick());
      refusal_log.flush();
      std::this_thread::sleep_for(kTick);
    }
  });
  std::cerr << "ready" << std::endl;

  int signal = 0;
  sigwait(&stop_signals, &signal);
  const auto signalled = std::chrono::steady_clock::now();
  stopping = true;
  ticker.join();
  if (feed) feed->stop();
  service->shutdown(kSubscriberDrain);
  server->Shutdown(std::chrono::system_clock::now() + kCallGrace);
  server->Wait();
  refusal_log.flush(true);
  const auto took = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - signalled);
  std::cerr << "tracker " << self->name << ": stopped " << took.count() << " ms after the signal\n";
  return EXIT_SUCCESS;
}

}  // namespace

int main(int argc, char** argv) {
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
    std::cerr << "tracker: " << e.what() << "\n";
    return kRuntimeFailure;
  }
}
