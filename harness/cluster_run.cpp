#include "harness/cluster_run.hpp"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "common/base/epochs.hpp"
#include "common/certs/certs.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/geometry/compact_view.hpp"
#include "common/sim/sensor_frames.hpp"
#include "common/sim/truth.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "harness/launcher.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/edge_runner.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap::harness {

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

// The collector's progress, for runCluster to start the edges only once it is subscribed.
struct Collection {
  std::mutex mutex;
  std::condition_variable changed;
  bool subscribed = false;
  bool ended = false;
  bool during_done = false;  // the caller's `during` returned: from then on `frames` epochs end the run
  RunResult result;
};

// Subscribes to the root (retrying until it listens) and keeps global maps until `frames` epochs
// arrived or the time runs out.
static void collect(const std::string& target, const std::shared_ptr<grpc::ChannelCredentials>& credentials, bool labels,
                    std::uint64_t frames, std::chrono::steady_clock::time_point deadline, Collection& out,
                    grpc::ClientContext& context) {
  const auto end = [&] {
    {
      std::lock_guard lock(out.mutex);
      out.ended = true;
    }
    out.changed.notify_all();
  };
  // A new channel per attempt: one channel retried while the root starts backs off (up to 2 s)
  // and would connect long after the root listens, missing the first epochs.
  std::shared_ptr<grpc::Channel> channel;
  for (;;) {
    channel = makeChannel(target, credentials, 256U << 20);
    if (channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::milliseconds(200))) break;
    if (std::chrono::steady_clock::now() > deadline || stopRequested()) return end();
  }
  auto stub = v1::GlobalMapService::NewStub(channel);
  v1::SubscribeRequest request;
  request.set_include_point_labels(labels);
  // Every epoch's first publication, late ones (after a stall of the root) included and flagged;
  // revisions are skipped below: they would overwrite the live picture geofences saw.
  auto reader = stub->Subscribe(&context, request);
  {
    std::lock_guard lock(out.mutex);
    out.subscribed = true;
  }
  out.changed.notify_all();
  v1::GlobalMap message;
  while (reader->Read(&message)) {
    auto global = fromProto(message);
    if (!global || global->revision != 0) continue;
    std::lock_guard lock(out.mutex);
    out.result.epochs[global->header.epoch] = std::move(*global);
    // Never while `during` runs: what it does (queries, attacks) is judged against these epochs.
    if (out.result.epochs.size() >= frames && out.during_done) break;
  }
  context.TryCancel();
  end();
}

Expected<RunResult> runCluster(const std::filesystem::path& dir, const TopologyConfig& topology, const RunOptions& options,
                               const std::function<void(const Cluster&)>& during) {
  const std::uint64_t frames = options.frames;
  const auto tls = loadTls(topology, options.identity, std::chrono::system_clock::now());
  if (!tls) return Error{tls.error().code, "tls: the subscriber's identity '" + options.identity + "': " + tls.error().message};
  const auto file = dir / (topology.name + ".yaml");
  {
    const std::string text = toYaml(topology);
    // Read back as the services will: a topology they would refuse stops the run here, naming
    // the key, instead of as a node that exits during start.
    if (const auto read_back = parseTopology(text, dir); !read_back) return read_back.error();
    std::ofstream out(file);
    out << text;
    if (!out) return ioError("cannot write " + file.string());
  }
  Collection collection;
  grpc::ClientContext context;
  const auto* root = topology.root();
  const auto deadline = std::chrono::steady_clock::now() + options.timeout;
  std::thread subscriber(collect, endpoint(root->host, root->port), channelCredentials(*tls),
                         options.point_labels, frames, deadline, std::ref(collection), std::ref(context));
  StartOptions start;
  start.prefixes = options.prefixes;
  start.aggregators_ready = [&] {
    // The edges start once the subscription stands (bounded: a root that cannot be reached is
    // the run's problem to report, not a reason to hang).
    std::unique_lock lock(collection.mutex);
    collection.changed.wait_for(lock, std::chrono::seconds(10), [&] { return collection.subscribed || collection.ended; });
  };
  auto cluster = startCluster(file, topology, dir / topology.name, std::chrono::seconds(30), start);
  if (!cluster) {
    context.TryCancel();
    subscriber.join();
    return cluster.error();
  }
  if (during) during(*cluster);
  {
    std::lock_guard lock(collection.mutex);
    collection.during_done = true;
  }
  // Wait for every epoch, or until the edges have finished their frames and the last epoch had
  // time to drain (one deadline and a margin), or the timeout.
  std::optional<std::chrono::steady_clock::time_point> edges_done;
  const auto drain = std::chrono::milliseconds(static_cast<long>(topology.deadline_ms) + 1000);
  while (std::chrono::steady_clock::now() < deadline && !stopRequested()) {
    {
      std::lock_guard lock(collection.mutex);
      if (collection.result.epochs.size() >= frames) break;
      if (options.complete_frames > 0 && completeEpochs(collection.result).size() >= options.complete_frames) {
        break;
      }
      if (options.enough && options.enough(collection.result)) break;
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
  RunResult result = std::move(collection.result);
  for (const auto& n : topology.nodes) {
    const auto text = httpGet(n.host, n.metrics_port, "/metrics", std::chrono::milliseconds(2000));
    if (text) result.metrics[n.name] = *text;
    // Every link ends at an aggregator, which stays up: its received bytes count every link.
    if (!text || n.role != Role::kAggregator) continue;
    result.bytes_moved += sumMetric(*text, "fogmap_bytes_received_total");
  }
  stopCluster(*cluster, std::chrono::milliseconds(5000));
  return result;
}

namespace {

// A simulated sensor's frames with their truth, as its edge casts them (SimScanSource).
class SimulatedFrames {
 public:
  static Expected<SimulatedFrames> open(const SensorConfig& sensor) {
    auto scene = sim::loadScene(sensor.scene);
    if (!scene) return scene.error();
    SimulatedFrames frames(std::move(*scene), sensor);
    if (frames.scene_.lidar(sensor.lidar) == nullptr) {
      return notFound("scene " + sensor.scene.string() + " has no LiDAR '" + sensor.lidar + "'");
    }
    return frames;
  }
  Expected<sim::SimFrame> at(std::uint64_t scan_number) {
    return sim::simulateScan(scene_, *scene_.lidar(lidar_), scan_number, rate_hz_, cache_);
  }

 private:
  SimulatedFrames(sim::Scene scene, const SensorConfig& sensor)
      : scene_(std::move(scene)), lidar_(sensor.lidar), rate_hz_(sensor.rate_hz) {}
  sim::Scene scene_;
  std::string lidar_;
  double rate_hz_;
  sim::RaycasterCache cache_;
};

}  // namespace

bool completeEpoch(const GlobalMapMessage& global) {
  return global.header.missing_nodes.empty() && !global.header.contributing_nodes.empty();
}

std::vector<std::uint64_t> completeEpochs(const RunResult& run) {
  std::vector<std::uint64_t> out;
  for (const auto& [e, g] : run.epochs) {
    if (completeEpoch(g)) out.push_back(e);
  }
  return out;
}

Expected<std::map<std::uint64_t, EdgeView>> recomputeEdges(const TopologyConfig& topology,
                                                           const std::vector<std::uint64_t>& epochs) {
  std::map<std::uint64_t, EdgeView> views;
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  for (const auto& n : topology.nodes) {
    if (n.role != Role::kEdge) continue;
    SensorConfig sensor = *n.sensor;  // any epoch, however many frames the run was limited to
    sensor.frames.reset();
    sensor.loop = true;
    std::optional<ScanSource> files;
    std::optional<SimulatedFrames> simulated;
    if (sensor.simulated()) {
      auto opened = SimulatedFrames::open(sensor);
      if (!opened) return opened.error();
      simulated.emplace(std::move(*opened));
    } else {
      auto opened = ScanSource::open(sensor);
      if (!opened) return opened.error();
      files.emplace(std::move(*opened));
    }
    EdgeConfig config = edgeConfigFor(topology, n);
    config.mode = Mode::kExt;
    EdgeNode edge(config);
    for (const auto e : epochs) {
      const std::uint64_t scan_number = scanNumberAt(*schedule, sensor.rate_hz, e);
      Cloud raw;
      std::optional<sim::SimFrame> frame;
      if (simulated) {
        auto cast = simulated->at(scan_number);
        if (!cast) return cast.error();
        frame.emplace(std::move(*cast));
        raw = frame->points;
      } else {
        auto read = files->at(scan_number);
        if (!read) return read.error();
        raw = std::move(read->points);
      }
      auto output = edge.processFrame(raw, e, 0);
      if (!output) return output.error();
      EdgeView& view = views[e];
      // The scan as the sensor gave it, shipped whole (the paper's baseline), in the same chunks.
      MapHeader whole;
      whole.node = n.id;
      whole.epoch = e;
      view.raw_bytes += baselineUploadBytes(whole, raw.size(), config.max_points_per_chunk, e);
      Cloud& points = view.points[n.id];
      std::vector<std::int32_t>& labels = view.local_labels[n.id];
      for (auto& chunk : output->chunks) {
        points.insert(points.end(), chunk.points.begin(), chunk.points.end());
        labels.insert(labels.end(), chunk.labels.begin(), chunk.labels.end());
        PointChunk raw_chunk = chunk;
        raw_chunk.labels.clear();  // the baseline ships points only
        v1::Upload upload;
        *upload.mutable_points() = toProto(raw_chunk);
        view.baseline_bytes += upload.ByteSizeLong();
      }
      if (frame) {
        // The processed points are in the common frame: so are the returns, once moved by the pose.
        Cloud returns;
        returns.reserve(frame->points.size());
        for (const Point& p : frame->points) {
          const Eigen::Vector3d q = sensor.pose * Eigen::Vector3d(p.x, p.y, p.z);
          returns.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()), p.intensity});
        }
        const double reach = std::max(0.05, config.preprocess.voxel_leaf_m.value_or(0.0));
        view.truth[n.id] = sim::truthOfPoints(points, returns, frame->truth, reach);
      }
      v1::Upload upload;
      *upload.mutable_map() = toProto(*output->map);
      view.madc_bytes += upload.ByteSizeLong();
      view.madc_ellipsoids += output->map->map.ellipsoidCount();
      MapMessage bare = *output->map;  // the same map without its views
      for (MapObject& object : bare.map.objects) {
        for (Ellipsoid& ellipsoid : object.ellipsoids) {
          if (hasView(ellipsoid)) ++view.madc_views;
          ellipsoid.box.reset();
          ellipsoid.label.reset();
        }
      }
      v1::Upload without_views;
      *without_views.mutable_map() = toProto(bare);
      view.madc_view_bytes += upload.ByteSizeLong() - without_views.ByteSizeLong();
      v1::Upload exact;
      *exact.mutable_map() = toProto(bare, EllipsoidWire::kExact);
      view.madc_exact_bytes += exact.ByteSizeLong();
      // What the parent receives: the map after its trip through the wire format.
      auto received = fromProto(upload.map());
      if (!received) return received.error();
      view.local_maps.push_back(received->map);
    }
  }
  return views;
}

void MapWireCost::add(const EdgeView& view) {
  bytes += view.madc_bytes;
  view_bytes += view.madc_view_bytes;
  exact_bytes += view.madc_exact_bytes;
  ellipsoids += view.madc_ellipsoids;
  views += view.madc_views;
}

namespace {
// amount / count, 0 for no count.
double per(std::size_t amount, std::size_t count) {
  return static_cast<double>(amount) / static_cast<double>(std::max<std::size_t>(count, 1));
}
}  // namespace

double MapWireCost::bytesPerEllipsoid() const { return per(bytes - view_bytes, ellipsoids); }
double MapWireCost::exactBytesPerEllipsoid() const { return per(exact_bytes, ellipsoids); }
double MapWireCost::viewBytesPerEllipsoid() const { return per(view_bytes, ellipsoids); }
double MapWireCost::viewShare() const { return per(views, ellipsoids); }
double MapWireCost::bytesPerFrame(std::size_t frames) const { return per(bytes, frames); }
double MapWireCost::viewBytesPerFrame(std::size_t frames) const { return per(view_bytes, frames); }

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

}  // namespace fogmap::harness
