// fogctl demo: a local MAD-C cluster and the baseline over the same real frames, side by side:
// objects, bytes per frame, merge and end-to-end latency, Rand index against the baseline, a
// bird's-eye PNG of the global map and a JSON report.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <numeric>
#include <Eigen/Eigenvalues>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/rand_index.hpp"
#include "common/topology.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/scan_source.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"
#include "tools/fogctl/launcher.hpp"

namespace fogmap::cli {
namespace {

int fail(const Error& e) {
  std::cerr << "fogctl demo: " << e.message << "\n";
  return e.code == ErrorCode::kInvalidArgument ? 2 : 1;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size()))) - 1;
  return v[std::min(k, v.size() - 1)];
}

// Sum of every sample of a counter family in a Prometheus text exposition.
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

struct RunResult {
  std::map<std::uint64_t, GlobalMapMessage> epochs;  // by epoch
  double bytes_sent = 0.0;                          // over every link of the cluster
  double frames = 0.0;                              // frames produced per edge
};

// Subscribes to the root (retrying until it listens) and keeps global maps until `frames` epochs
// arrived or the time runs out.
void collect(const std::string& target, bool labels, std::uint64_t frames, std::chrono::steady_clock::time_point deadline,
             RunResult& out, std::mutex& mutex, grpc::ClientContext& context) {
  auto channel = makeChannel(target, 256U << 20);
  while (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::milliseconds(200))) {
    if (std::chrono::steady_clock::now() > deadline || stopRequested()) return;
  }
  auto stub = v1::GlobalMapService::NewStub(channel);
  v1::SubscribeRequest request;
  request.set_include_point_labels(labels);
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

Expected<RunResult> runCluster(const std::filesystem::path& dir, const TopologyConfig& topology, std::uint64_t frames,
                               double rate_hz) {
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
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30) +
                        std::chrono::milliseconds(static_cast<long>(1000.0 * static_cast<double>(frames) / rate_hz * 3.0));
  std::thread subscriber(collect, root->host + ":" + std::to_string(root->port), topology.mode != Mode::kMadc, frames,
                         deadline, std::ref(result), std::ref(mutex), std::ref(context));
  auto cluster = startCluster(file, topology, dir / topology.name, std::chrono::seconds(30));
  if (!cluster) {
    context.TryCancel();
    subscriber.join();
    return cluster.error();
  }
  // Wait for every epoch (the edges stop after `frames` frames) or the deadline.
  while (std::chrono::steady_clock::now() < deadline && !stopRequested()) {
    {
      std::lock_guard lock(mutex);
      if (result.epochs.size() >= frames) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  context.TryCancel();
  subscriber.join();
  for (const auto& n : topology.nodes) {
    const auto text = httpGet(n.host, n.metrics_port, "/metrics", std::chrono::milliseconds(2000));
    if (!text) continue;  // an edge that finished its frames has exited
    result.bytes_sent += sumMetric(*text, "fogmap_bytes_sent_total");
    result.frames = std::max(result.frames, sumMetric(*text, "fogmap_frames_total"));
  }
  stopCluster(*cluster, std::chrono::milliseconds(5000));
  return result;
}

// The edges' view of one epoch, recomputed with the same library code: pre-processed points and
// local cluster labels per sensor, and the bytes each edge shipped in both modes.
struct EdgeView {
  std::map<std::uint32_t, std::vector<std::int32_t>> local_labels;
  std::map<std::uint32_t, Cloud> points;
  std::size_t madc_bytes = 0;
  std::size_t baseline_bytes = 0;
};

Expected<std::vector<EdgeView>> recomputeEdges(const TopologyConfig& topology, std::uint64_t frames) {
  std::vector<EdgeView> views(frames);
  for (const auto& n : topology.nodes) {
    if (n.role != Role::kEdge) continue;
    auto source = ScanSource::open(*n.sensor);
    if (!source) return source.error();
    EdgeConfig config = edgeConfigFor(topology, n);
    config.mode = Mode::kExt;
    const EdgeNode edge(config);
    for (std::uint64_t e = 0; e < frames && !source->done(); ++e) {
      auto frame = source->next();
      if (!frame) return frame.error();
      auto output = edge.processFrame(frame->points, frame->sequence, 0);
      if (!output) return output.error();
      EdgeView& view = views[frame->sequence];
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
    }
  }
  return views;
}

struct Accuracy {
  RandScores clusters;  // elements = local clusters (the paper)
  RandScores points;    // elements = points
  bool ok = false;
};

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
    if (it == central.end() || it->second->size() != labels.size()) return {};
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

// Bird's-eye view: points grey, each global object's ellipsoids in the object's colour.
Status drawPng(const std::filesystem::path& file, const GlobalMapMessage& global, const EdgeView& view, double half_extent_m) {
  constexpr int kSize = 1000;
  cv::Mat image(kSize, kSize, CV_8UC3, cv::Scalar(255, 255, 255));
  const double scale = kSize / (2.0 * half_extent_m);
  auto pixel = [&](double x, double y) { return cv::Point2d((half_extent_m - y) * scale, (half_extent_m - x) * scale); };  // x up, y left
  for (const auto& [node, cloud] : view.points) {
    for (const auto& p : cloud) {
      const auto px = pixel(p.x, p.y);
      if (px.x >= 0 && px.y >= 0 && px.x < kSize && px.y < kSize) image.at<cv::Vec3b>(static_cast<int>(px.y), static_cast<int>(px.x)) = {170, 170, 170};
    }
  }
  for (std::size_t o = 0; o < global.map.objects.size(); ++o) {
    const auto hue = static_cast<unsigned char>((o * 47) % 180);
    cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(hue, 220, 210));
    cv::Mat bgr;
    cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
    const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
    for (const auto& e : global.map.objects[o].ellipsoids) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(e.shape.topLeftCorner<2, 2>());
      const Eigen::Vector2d axes = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt() * scale;
      const Eigen::Vector2d major = solver.eigenvectors().col(1);
      // Image x = -y, image y = -x: the angle of the major axis in image coordinates.
      const double angle = std::atan2(-major.x(), -major.y()) * 180.0 / M_PI;
      cv::ellipse(image, pixel(e.center.x(), e.center.y()), cv::Size2d(axes[1], axes[0]), angle, 0, 360, cv::Scalar(c[0], c[1], c[2]), 2,
                  cv::LINE_AA);
    }
  }
  cv::circle(image, pixel(0, 0), 4, cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(image, "fogmap global map, epoch " + std::to_string(global.header.epoch) + ": " + std::to_string(global.map.objects.size()) + " objects",
              cv::Point(10, 25), cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 0), 2);
  if (!cv::imwrite(file.string(), image)) return ioError("cannot write " + file.string());
  return {};
}

std::filesystem::path defaultInput() {
  for (const auto& candidate : {binaryDir() / ".." / ".." / "data" / "kitti_raw_seq_a", std::filesystem::path("data/kitti_raw_seq_a")}) {
    if (std::filesystem::is_directory(candidate)) return std::filesystem::canonical(candidate);
  }
  return {};
}

}  // namespace

int runDemo(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"input", "nodes", "topology", "frames", "report", "png", "base-port", "state", "alpha"}, {});
  if (!args) return fail(args.error());
  const std::filesystem::path input = args->has("input") ? std::filesystem::absolute(args->get("input")) : defaultInput();
  if (input.empty() || !std::filesystem::exists(input)) return fail(invalidArgument("--input DIR of scans is required (bundled data not found)"));
  const auto nodes = args->getInt("nodes", 4);
  const auto frames = args->getInt("frames", 20);
  const auto base = args->getInt("base-port", 46000);
  const auto alpha = args->getDouble("alpha", 1.5);
  if (!nodes || *nodes < 1 || *nodes > 32) return fail(invalidArgument("--nodes must be in [1, 32]"));
  if (!frames || *frames < 1 || *frames > 10000) return fail(invalidArgument("--frames must be in [1, 10000]"));
  if (!base || *base < 1024 || *base > 60000) return fail(invalidArgument("--base-port must be in [1024, 60000]"));
  if (!alpha || !(*alpha > 0.0)) return fail(invalidArgument("--alpha must be positive"));
  const std::string shape = args->get("topology", "star");
  if (shape != "star" && shape != "tree") return fail(invalidArgument("--topology must be star or tree"));
  const std::filesystem::path dir = args->get("state", ".fogmap/demo");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  installStopHandlers();

  auto make = [&](Mode mode, int port) {
    TopologyConfig t = shape == "star" ? makeStarTopology(static_cast<int>(*nodes), input, port)
                                       : makeTreeTopology(static_cast<int>(*nodes), input, port);
    t.mode = mode;
    t.name = std::string(modeName(mode)) + "-" + t.name;
    t.madc.alpha = *alpha;
    for (auto& n : t.nodes) {
      if (n.sensor) n.sensor->frames = static_cast<std::uint64_t>(*frames);
    }
    return t;
  };
  const TopologyConfig madc_topology = make(Mode::kMadc, static_cast<int>(*base));
  const TopologyConfig baseline_topology = make(Mode::kBaseline, static_cast<int>(*base) + 400);
  const double rate_hz = madc_topology.nodes.back().sensor->rate_hz;
  const auto n_frames = static_cast<std::uint64_t>(*frames);

  std::printf("fogmap demo: %ld virtual LiDARs cut from %s, %s topology, %lu frames at %.0f Hz, alpha %.2f\n", *nodes,
              input.c_str(), shape.c_str(), static_cast<unsigned long>(n_frames), rate_hz, *alpha);
  std::printf("running the MAD-C cluster (%zu services)...\n", madc_topology.nodes.size());
  auto madc = runCluster(dir, madc_topology, n_frames, rate_hz);
  if (!madc) return fail(madc.error());
  if (stopRequested()) return 1;
  std::printf("running the baseline cluster (ship all points, cluster at the sink)...\n");
  auto baseline = runCluster(dir, baseline_topology, n_frames, rate_hz);
  if (!baseline) return fail(baseline.error());
  auto views = recomputeEdges(madc_topology, n_frames);
  if (!views) return fail(views.error());

  std::printf("\n%6s %8s %8s %12s %14s %8s %9s %9s %8s %8s\n", "frame", "objects", "baseline", "bytes MAD-C", "bytes baseline",
              "ratio", "merge ms", "e2e ms", "RI", "ARI");
  std::vector<double> e2e_ms;
  std::vector<double> merge_ms;
  std::vector<double> ri;
  std::vector<double> ari;
  std::vector<double> ri_points;
  const GlobalMapMessage* last = nullptr;
  std::uint64_t last_epoch = 0;
  for (std::uint64_t e = 0; e < n_frames; ++e) {
    const auto m = madc->epochs.find(e);
    const auto b = baseline->epochs.find(e);
    if (m == madc->epochs.end() || b == baseline->epochs.end()) {
      std::printf("%6lu   (not received from both clusters)\n", static_cast<unsigned long>(e));
      continue;
    }
    const EdgeView& view = (*views)[e];
    const Accuracy a = accuracy(m->second, b->second, view);
    const double e2e = static_cast<double>(m->second.published_time_ns - m->second.header.sensor_time_ns) / 1e6;
    e2e_ms.push_back(e2e);
    merge_ms.push_back(m->second.merge_seconds * 1e3);
    if (a.ok) {
      ri.push_back(a.clusters.rand_index);
      ari.push_back(a.clusters.adjusted_rand_index);
      ri_points.push_back(a.points.rand_index);
    }
    std::printf("%6lu %8zu %8zu %12zu %14zu %7.0fx %9.3f %9.1f %8.4f %8.4f%s\n", static_cast<unsigned long>(e),
                m->second.map.objects.size(), b->second.map.objects.size(), view.madc_bytes, view.baseline_bytes,
                static_cast<double>(view.baseline_bytes) / static_cast<double>(std::max<std::size_t>(view.madc_bytes, 1)),
                merge_ms.back(), e2e, a.ok ? a.clusters.rand_index : 0.0, a.ok ? a.clusters.adjusted_rand_index : 0.0,
                a.ok ? "" : "  (labels missing)");
    last = &m->second;
    last_epoch = e;
  }
  if (e2e_ms.empty()) return fail(Error{ErrorCode::kInternal, "no epoch arrived from both clusters; see the logs in " + dir.string()});
  auto mean = [](const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size()); };
  const double frames_done = std::max(1.0, std::min(madc->frames, baseline->frames));
  const double madc_per_frame = madc->bytes_sent / std::max(1.0, madc->frames);
  const double baseline_per_frame = baseline->bytes_sent / std::max(1.0, baseline->frames);
  const double ratio = baseline_per_frame / std::max(1.0, madc_per_frame);
  std::printf("\ntotal over %zu frames compared (%.0f produced per edge)\n", e2e_ms.size(), frames_done);
  std::printf("  bytes per frame, all links:  MAD-C %.0f B   baseline %.0f B   ratio %.0fx\n", madc_per_frame, baseline_per_frame, ratio);
  std::printf("  merge latency at the sink:   p50 %.3f ms   p99 %.3f ms\n", percentile(merge_ms, 0.5), percentile(merge_ms, 0.99));
  std::printf("  end-to-end latency:          p50 %.1f ms   p99 %.1f ms   (sensor timestamp to global map)\n",
              percentile(e2e_ms, 0.5), percentile(e2e_ms, 0.99));
  std::printf("  accuracy vs baseline:        Rand index %.4f   adjusted %.4f   (local clusters); Rand index %.4f (points)\n",
              mean(ri), mean(ari), mean(ri_points));

  const std::filesystem::path png = args->get("png", (dir / "global_map.png").string());
  if (last != nullptr) {
    if (const Status s = drawPng(png, *last, (*views)[last_epoch], 40.0); !s) return fail(s.error());
    std::printf("  bird's-eye view of frame %lu: %s\n", static_cast<unsigned long>(last_epoch), png.c_str());
  }
  const std::filesystem::path report = args->get("report", (dir / "report.json").string());
  std::ofstream out(report);
  out << "{\n"
      << "  \"topology\": \"" << shape << "\",\n"
      << "  \"nodes\": " << *nodes << ",\n"
      << "  \"input\": \"" << input.string() << "\",\n"
      << "  \"frames\": " << e2e_ms.size() << ",\n"
      << "  \"alpha\": " << *alpha << ",\n"
      << "  \"bytes_madc_per_frame\": " << madc_per_frame << ",\n"
      << "  \"bytes_baseline_per_frame\": " << baseline_per_frame << ",\n"
      << "  \"bytes_ratio\": " << ratio << ",\n"
      << "  \"rand_index_mean\": " << mean(ri) << ",\n"
      << "  \"ari_mean\": " << mean(ari) << ",\n"
      << "  \"rand_index_points_mean\": " << mean(ri_points) << ",\n"
      << "  \"e2e_p50_ms\": " << percentile(e2e_ms, 0.5) << ",\n"
      << "  \"e2e_p99_ms\": " << percentile(e2e_ms, 0.99) << ",\n"
      << "  \"merge_p50_ms\": " << percentile(merge_ms, 0.5) << ",\n"
      << "  \"merge_p99_ms\": " << percentile(merge_ms, 0.99) << "\n"
      << "}\n";
  if (!out) return fail(ioError("cannot write " + report.string()));
  std::printf("  report: %s\n", report.c_str());
  return 0;
}

}  // namespace fogmap::cli
