// fogctl cluster / fogctl bench clustering: the core pipeline on one scan.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>
#include <vector>

#include "common/admission.hpp"
#include "common/cloud_io.hpp"
#include "common/clustering.hpp"
#include "common/preprocess.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

double millisSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

Expected<ClusteringParams> clusteringParams(const Args& args) {
  ClusteringParams p;
  const auto eps = args.getDouble("eps", p.eps_m);
  if (!eps) return eps.error();
  const auto min_points = args.getInt("min-points", static_cast<long>(p.min_points));
  if (!min_points) return min_points.error();
  const auto threads = args.getInt("threads", static_cast<long>(std::max(1U, std::thread::hardware_concurrency())));
  if (!threads) return threads.error();
  if (*threads < 1 || *threads > 256) return invalidArgument("--threads must be between 1 and 256");
  p.eps_m = *eps;
  // A negative count would wrap to a huge size_t; 0 gets validateClusteringParams' own message.
  p.min_points = static_cast<std::size_t>(std::max(0L, *min_points));
  p.threads = static_cast<std::size_t>(*threads);
  if (const Status valid = validateClusteringParams(p); !valid) {
    return invalidArgument("--eps/--min-points: " + valid.error().message);
  }
  return p;
}

// Reads --input within --max-scan-bytes; non-finite points are kept in place (they cluster as
// noise) when `keep_non_finite`, so that the cloud lines up with the file point for point.
Expected<Cloud> loadScan(const Args& args, bool keep_non_finite) {
  if (!args.has("input")) return invalidArgument("--input SCAN is required");
  const auto max_bytes = args.getInt("max-scan-bytes", static_cast<long>(kDefaultMaxScanBytes));
  if (!max_bytes || *max_bytes < 1) return invalidArgument("--max-scan-bytes expects a positive number of bytes");
  const ReadLimits limits{static_cast<std::uintmax_t>(*max_bytes), keep_non_finite};
  const std::filesystem::path input = args.get("input");
  auto loaded = readCloud(input, limits);
  if (!loaded) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(input, ec);
    if (!ec && size > limits.max_bytes) {
      return Error{loaded.error().code, loaded.error().message + "; raise the bound with --max-scan-bytes"};
    }
    return loaded.error();
  }
  if (loaded->dropped_non_finite > 0) {
    std::cerr << "fogctl: dropped " << loaded->dropped_non_finite << " non-finite points\n";
  }
  if (loaded->kept_non_finite > 0) {
    std::cerr << "fogctl: " << loaded->kept_non_finite << " non-finite points, labelled noise\n";
  }
  if (!args.has("remove-ground")) return std::move(loaded->points);
  auto ground = removeGround(loaded->points, GroundParams{});
  if (!ground) return ground.error();
  return std::move(ground->non_ground);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int benchClustering(int argc, char** argv) {
  const auto args =
      Args::parse(argc, argv, 3, {"input", "eps", "min-points", "repeat", "threads", "max-scan-bytes"}, {"remove-ground", "json"});
  if (!args) return fail(args.error());
  const auto params = clusteringParams(*args);
  if (!params) return fail(params.error());
  const auto cloud = loadScan(*args, false);
  if (!cloud) return fail(cloud.error());
  const auto repeat = args->getInt("repeat", 5);
  if (!repeat || *repeat < 1) return fail(invalidArgument("--repeat expects a positive integer"));

  auto timed = [&](ClusteringMethod method, long runs, Clustering* out, std::size_t threads = 1) {
    ClusteringParams p = *params;
    p.threads = threads;
    std::vector<double> ms;
    for (long r = 0; r < runs; ++r) {
      const auto start = Clock::now();
      *out = clusterPoints(*cloud, p, method);
      ms.push_back(millisSince(start));
    }
    return median(ms);
  };
  Clustering pcl_sorted;
  Clustering pcl_unsorted;
  Clustering ours;
  Clustering ours_one;
  const double pcl_sorted_ms = timed(ClusteringMethod::kPcl, *repeat, &pcl_sorted);
  const double pcl_unsorted_ms = timed(ClusteringMethod::kPclUnsorted, *repeat, &pcl_unsorted);
  const double one_ms = timed(ClusteringMethod::kFogmap, *repeat * 4, &ours_one);
  const double ours_ms = params->threads > 1 ? timed(ClusteringMethod::kFogmap, *repeat * 4, &ours, params->threads) : one_ms;
  if (params->threads <= 1) ours = ours_one;
  const bool sorted_faster = pcl_sorted_ms <= pcl_unsorted_ms;
  const double pcl_ms = sorted_faster ? pcl_sorted_ms : pcl_unsorted_ms;
  const Clustering& reference = sorted_faster ? pcl_sorted : pcl_unsorted;
  const bool identical = ours.labels == reference.labels && ours_one.labels == reference.labels;
  const bool identical_both = identical && ours.labels == pcl_sorted.labels && ours.labels == pcl_unsorted.labels;
  const double speedup = pcl_ms / ours_ms;
  const double speedup_one = pcl_ms / one_ms;

  if (args->has("json")) {
    std::printf(
        "{\"input\": \"%s\", \"points\": %zu, \"eps\": %.4g, \"min_points\": %zu, \"remove_ground\": %s, "
        "\"clusters\": %d, \"pcl_sorted_ms\": %.3f, \"pcl_unsorted_ms\": %.3f, \"pcl_ms\": %.3f, "
        "\"threads\": %zu, \"fogmap_ms\": %.3f, \"speedup\": %.2f, \"fogmap_1thread_ms\": %.3f, \"speedup_1thread\": %.2f, "
        "\"identical\": %s, \"identical_to_both_pcl\": %s}\n",
        args->get("input").c_str(), cloud->size(), params->eps_m, params->min_points,
        args->has("remove-ground") ? "true" : "false", ours.cluster_count, pcl_sorted_ms, pcl_unsorted_ms, pcl_ms,
        params->threads, ours_ms, speedup, one_ms, speedup_one, identical ? "true" : "false", identical_both ? "true" : "false");
  } else {
    std::printf("points            %zu%s\n", cloud->size(), args->has("remove-ground") ? " (ground removed)" : "");
    std::printf("clusters          %d (eps %.3g m, min %zu points)\n", ours.cluster_count, params->eps_m, params->min_points);
    std::printf("pcl sorted        %9.2f ms (median of %ld)\n", pcl_sorted_ms, *repeat);
    std::printf("pcl unsorted      %9.2f ms (median of %ld)\n", pcl_unsorted_ms, *repeat);
    std::printf("fogmap, 1 thread  %9.2f ms (median of %ld), %.1fx against the faster PCL setting\n", one_ms, *repeat * 4, speedup_one);
    if (params->threads > 1) {
      std::printf("fogmap, %zu threads %8.2f ms (median of %ld), %.1fx against the faster PCL setting\n", params->threads, ours_ms, *repeat * 4, speedup);
    }
    std::printf("identical         %s\n", identical ? "yes (same partition as PCL, every thread count)" : "NO");
  }
  return identical ? 0 : 1;
}

}  // namespace

int runCluster(int argc, char** argv) {
  const auto args =
      Args::parse(argc, argv, 2, {"input", "eps", "min-points", "labels", "method", "threads", "max-scan-bytes"}, {"remove-ground"});
  if (!args) return fail(args.error());
  const auto params = clusteringParams(*args);
  if (!params) return fail(params.error());
  const std::string method_name = args->get("method", "fogmap");
  ClusteringMethod method = ClusteringMethod::kFogmap;
  if (method_name == "pcl") {
    method = ClusteringMethod::kPcl;
  } else if (method_name != "fogmap") {
    return fail(invalidArgument("--method must be fogmap or pcl, got '" + method_name + "'"));
  }
  const auto cloud = loadScan(*args, true);
  if (!cloud) return fail(cloud.error());
  const auto start = Clock::now();
  const Clustering clustering = clusterPoints(*cloud, *params, method);
  const double ms = millisSince(start);
  if (args->has("labels")) {
    std::ofstream out(args->get("labels"));
    if (!out) return fail(ioError("cannot write labels to " + args->get("labels")));
    for (const auto l : clustering.labels) out << l << '\n';
    if (!out) return fail(ioError("writing labels to " + args->get("labels") + " failed"));
  }
  std::printf("%zu points, %d clusters, %.2f ms (%s)\n", cloud->size(), clustering.cluster_count, ms, method_name.c_str());
  return 0;
}

int runBench(int argc, char** argv) {
  if (argc < 3 || std::string(argv[2]) != "clustering") {
    std::cerr << "usage: fogctl bench clustering --input SCAN [--eps 0.35 --min-points 10] [--remove-ground] [--json]"
                 " [--max-scan-bytes N]\n";
    return 2;
  }
  return benchClustering(argc, argv);
}

}  // namespace fogmap::cli
