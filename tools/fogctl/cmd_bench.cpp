// fogctl bench clustering: fogmap's clustering timed against PCL's on one scan, and checked to
// give the same partition.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "common/perception/clustering.hpp"
#include "harness/report_text.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

// `v` as printf's `format` writes it, read back: the report's figures carry the printed precision.
double asPrinted(const char* format, double v) {
  char text[64];
  std::snprintf(text, sizeof text, format, v);
  return std::strtod(text, nullptr);
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
      ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
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
    harness::Json report;
    report["input"] = args->get("input");
    report["points"] = cloud->size();
    report["eps"] = asPrinted("%.4g", params->eps_m);
    report["min_points"] = params->min_points;
    report["remove_ground"] = args->has("remove-ground");
    report["clusters"] = ours.cluster_count;
    report["pcl_sorted_ms"] = asPrinted("%.3f", pcl_sorted_ms);
    report["pcl_unsorted_ms"] = asPrinted("%.3f", pcl_unsorted_ms);
    report["pcl_ms"] = asPrinted("%.3f", pcl_ms);
    report["threads"] = params->threads;
    report["fogmap_ms"] = asPrinted("%.3f", ours_ms);
    report["speedup"] = asPrinted("%.2f", speedup);
    report["fogmap_1thread_ms"] = asPrinted("%.3f", one_ms);
    report["speedup_1thread"] = asPrinted("%.2f", speedup_one);
    report["identical"] = identical;
    report["identical_to_both_pcl"] = identical_both;
    // One line per run, so that runs append to a JSON Lines file.
    std::printf("%s\n", report.dump(-1, ' ', false, harness::Json::error_handler_t::replace).c_str());
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

int runBench(int argc, char** argv) {
  if (argc < 3 || std::string(argv[2]) != "clustering") {
    std::cerr << "usage: fogctl bench clustering --input SCAN [--eps 0.35 --min-points 10] [--remove-ground] [--json]"
                 " [--max-scan-bytes N]\n";
    return 2;
  }
  return benchClustering(argc, argv);
}

}  // namespace

Command benchCommand() {
  return {"bench",
          "clustering --input SCAN [--eps 0.35] [--min-points 10] [--remove-ground] [--repeat 5] [--threads N] [--json]",
          "usage: fogctl bench clustering --input SCAN [--eps 0.35] [--min-points 10] [--remove-ground] [--repeat 5]\n"
          "                               [--threads N] [--json] [--max-scan-bytes N]\n"
          "Times fogmap's clustering against PCL's on one scan (median of --repeat runs) and checks that\n"
          "both give the same partition; exits 1 when they do not.\n",
          runBench};
}

}  // namespace fogmap::cli
