#include "tools/fogctl/cluster_run.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "common/certs.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/scan_source.hpp"
#include "tools/fogctl/launcher.hpp"

namespace fogmap::cli {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size()))) - 1;
  return v[std::min(k, v.size() - 1)];
}

double sumMetric(const std::string& text, const std::string& name) {
  double total = 0.0;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(name, 0) != 0) continue;
    const char next = line.size() > name.size() ? line[name.size()] : ' ';
    if (next != '{' && next != ' ') continue;
    total += std::strtod(line.substr(line.rfind(' ') + 1).c_str(), nullptr);
  }
  return total;
}

// Subscribes to the root (retrying until it listens) and keeps global maps until `frames` epochs
// arrived or the time runs out.
static void collect(const std::string& target, const std::shared_ptr<grpc::ChannelCredentials>& credentials, bool labels,
                    std::uint64_t frames, std::chrono::steady_clock::time_point deadline, RunResult& out, std::mutex& mutex,
                    grpc::ClientContext& context) {
  auto channel = makeChannel(target, credentials, 256U << 20);
  while (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::milliseconds(200))) {
    if (std::chrono::steady_clock::now() > deadline || stopRequested()) return;
  }
  auto stub = v1::GlobalMapService::NewStub(channel);
  v1::SubscribeRequest request;
  request.set_include_point_labels(labels);
  request.set_on_time_only(true);  // the live picture, as geofences see it; revisions would overwrite it
  auto reader = stub->Subscribe(&context, request);
  v1::GlobalMap message;
  while (reader->Read(&message)) {
    auto global = fromProto(message);
    if (!global) continue;
    std::lock_guard lock(mutex);
    out.epochs[global->header.epoch] = std::move(*global);
    if (out.epochs.size() >= frames) break;
  }
  context.TryCancel();
}

Expected<RunResult> runCluster(const std::filesystem::path& dir, const TopologyConfig& topology, const RunOptions& options,
                               const std::function<void(const Cluster&)>& during) {
  const std::uint64_t frames = options.frames;
  const auto tls = loadTls(topology, options.identity, std::chrono::system_clock::now());
  if (!tls) return Error{tls.error().code, "tls: the subscriber's identity '" + options.identity + "': " + tls.error().message};
  const auto file = dir / (topology.name + ".yaml");
  {
    std::ofstream out(file);
    out << toYaml(topology);
    if (!out) return ioError("cannot write " + file.string());
  }
  RunResult result;
  std::mutex mutex;
  grpc::ClientContext context;
  const auto* root = topology.root();
  const auto deadline = std::chrono::steady_clock::now() + options.timeout;
  std::thread subscriber(collect, root->host + ":" + std::to_string(root->port), channelCredentials(*tls),
                         options.point_labels, frames, deadline, std::ref(result), std::ref(mutex), std::ref(context));
  auto cluster = startCluster(file, topology, dir / topology.name, std::chrono::seconds(30));
  if (!cluster) {
    context.TryCancel();
    subscriber.join();
    return cluster.error();
  }
  if (during) during(*cluster);
  // Wait for every epoch, or until the edges have finished their frames and the last epoch had
  // time to drain (one deadline and a margin), or the timeout.
  std::optional<std::chrono::steady_clock::time_point> edges_done;
  const auto drain = std::chrono::milliseconds(static_cast<long>(topology.deadline_ms) + 1000);
  while (std::chrono::steady_clock::now() < deadline && !stopRequested()) {
    {
      std::lock_guard lock(mutex);
      if (result.epochs.size() >= frames) break;
    }
    if (!edges_done) {
      bool any_edge = false;
      for (const auto& n : cluster->nodes) {
        const NodeConfig* config = topology.find(n.name);
        any_edge = any_edge || (config != nullptr && config->role == Role::kEdge && isRunning(n.pid));
      }
      if (!any_edge) edges_done = std::chrono::steady_clock::now();
    } else if (std::chrono::steady_clock::now() > *edges_done + drain) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  context.TryCancel();
  subscriber.join();
  for (const auto& n : topology.nodes) {
    const auto text = httpGet(n.host, n.metrics_port, "/metrics", std::chrono::milliseconds(2000));
    // Every link ends at an aggregator, which stays up: its received bytes count every link.
    if (!text || n.role != Role::kAggregator) continue;
    result.bytes_moved += sumMetric(*text, "fogmap_bytes_received_total");
  }
  stopCluster(*cluster, std::chrono::milliseconds(5000));
  return result;
}

Expected<std::map<std::uint64_t, EdgeView>> recomputeEdges(const TopologyConfig& topology,
                                                           const std::vector<std::uint64_t>& epochs) {
  std::map<std::uint64_t, EdgeView> views;
  for (const auto& n : topology.nodes) {
    if (n.role != Role::kEdge) continue;
    SensorConfig sensor = *n.sensor;  // any epoch, however many frames the run was limited to
    sensor.frames.reset();
    sensor.loop = true;
    auto source = ScanSource::open(sensor);
    if (!source) return source.error();
    EdgeConfig config = edgeConfigFor(topology, n);
    config.mode = Mode::kExt;
    const EdgeNode edge(config);
    for (const auto e : epochs) {
      auto frame = source->at(e);
      if (!frame) return frame.error();
      auto output = edge.processFrame(frame->points, e, 0);
      if (!output) return output.error();
      EdgeView& view = views[e];
      Cloud& points = view.points[n.id];
      std::vector<std::int32_t>& labels = view.local_labels[n.id];
      for (auto& chunk : output->chunks) {
        points.insert(points.end(), chunk.points.begin(), chunk.points.end());
        labels.insert(labels.end(), chunk.labels.begin(), chunk.labels.end());
        PointChunk raw = chunk;
        raw.labels.clear();  // the baseline ships points only
        v1::Upload upload;
        *upload.mutable_points() = toProto(raw);
        view.baseline_bytes += upload.ByteSizeLong();
      }
      v1::Upload upload;
      *upload.mutable_map() = toProto(*output->map);
      view.madc_bytes += upload.ByteSizeLong();
      // What the parent receives: the map after its trip through the wire format.
      auto received = fromProto(upload.map());
      if (!received) return received.error();
      view.local_maps.push_back(received->map);
    }
  }
  return views;
}

Accuracy accuracy(const GlobalMapMessage& madc, const GlobalMapMessage& baseline, const EdgeView& view) {
  std::map<EllipsoidId, std::int64_t> object_of;
  for (std::size_t o = 0; o < madc.map.objects.size(); ++o) {
    for (const auto& e : madc.map.objects[o].ellipsoids) object_of[e.id] = static_cast<std::int64_t>(o);
  }
  std::map<std::uint32_t, const std::vector<std::int32_t>*> central;
  for (const auto& nl : baseline.point_labels) central[nl.node] = &nl.labels;
  std::vector<std::int64_t> point_madc;
  std::vector<std::int64_t> point_base;
  std::vector<std::int64_t> cluster_madc;
  std::vector<std::int64_t> cluster_base;
  std::int64_t noise = -1;  // every noise element its own singleton: distinct negative labels
  for (const auto& [node, labels] : view.local_labels) {
    const auto it = central.find(node);
    if (it == central.end() || it->second->size() != labels.size()) {
      Accuracy failed;
      failed.problem = "node " + std::to_string(node) + ": baseline has " +
                       (it == central.end() ? std::string("no labels") : std::to_string(it->second->size()) + " labels") +
                       ", the edge " + std::to_string(labels.size()) + " points";
      return failed;
    }
    const auto& base = *it->second;
    std::map<std::int32_t, std::map<std::int32_t, std::size_t>> votes;  // local cluster -> central label -> count
    for (std::size_t i = 0; i < labels.size(); ++i) {
      const auto l = labels[i];
      std::int64_t m = noise--;
      if (l >= 0) {
        const auto found = object_of.find({node, madc.header.epoch, static_cast<std::uint32_t>(l)});
        if (found != object_of.end()) m = found->second;
        ++votes[l][base[i]];
      }
      point_madc.push_back(m);
      point_base.push_back(base[i] >= 0 ? base[i] : noise--);
    }
    for (const auto& [l, count] : votes) {
      const auto found = object_of.find({node, madc.header.epoch, static_cast<std::uint32_t>(l)});
      cluster_madc.push_back(found != object_of.end() ? found->second : noise--);
      const auto best = std::max_element(count.begin(), count.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      cluster_base.push_back(best->first >= 0 ? best->first : noise--);
    }
  }
  Accuracy a;
  const auto c = randScores(cluster_madc, cluster_base);
  const auto p = randScores(point_madc, point_base);
  if (!c || !p) return a;
  a.clusters = *c;
  a.points = *p;
  a.ok = true;
  return a;
}

}  // namespace fogmap::cli
