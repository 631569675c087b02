// fogctl cluster: the core pipeline on one scan: its clusters, and a label per point.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>

#include "common/io/cloud_io.hpp"
#include "common/perception/clustering.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

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
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  if (args->has("labels")) {
    std::ofstream out(args->get("labels"));
    if (!out) return fail(ioError("cannot write labels to " + args->get("labels")));
    for (const auto l : clustering.labels) out << l << '\n';
    if (!out) return fail(ioError("writing labels to " + args->get("labels") + " failed"));
  }
  std::printf("%zu points, %d clusters, %.2f ms (%s)\n", cloud->size(), clustering.cluster_count, ms, method_name.c_str());
  return 0;
}

}  // namespace

Command clusterCommand() {
  return {"cluster",
          "--input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--method fogmap|pcl] [--remove-ground] [--threads N]",
          "usage: fogctl cluster --input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--method fogmap|pcl]\n"
          "                      [--remove-ground] [--threads N] [--max-scan-bytes N]\n"
          "Clusters one scan (KITTI .bin, nuScenes .pcd.bin, PCD) and prints the number of clusters.\n"
          "  --eps M              clustering radius in metres, 0.001 to 100 (default 0.35)\n"
          "  --min-points N       smallest cluster, in points (default 10)\n"
          "  --labels FILE        one label per point of the file, in its order: the cluster, -1 for noise\n"
          "                       (non-finite points are noise); with --remove-ground, per non-ground point\n"
          "  --method fogmap|pcl  fogmap's grid clustering or PCL's, the reference (default fogmap)\n"
          "  --remove-ground      remove the ground before clustering\n"
          "  --threads N          threads for the neighbour search (default: one per core)\n"
          "  --max-scan-bytes N   refuse larger files unread (default " + std::to_string(fogmap::kDefaultMaxScanBytes) + ")\n",
          runCluster};
}

}  // namespace fogmap::cli
