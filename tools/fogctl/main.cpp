// fogctl: the command-line front of fogmap.
#include <cstring>
#include <iostream>
#include <string>

#include "tools/fogctl/commands.hpp"

namespace {

void usage() {
  std::cerr << "usage: fogctl <command> [flags]\n"
               "  cluster --input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--method fogmap|pcl] [--remove-ground] [--threads N]\n"
               "  bench clustering --input SCAN [--eps 0.35] [--min-points 10] [--remove-ground] [--repeat 5] [--threads N] [--json]\n"
               "  demo [--input DIR] [--nodes 4] [--topology star|tree] [--frames 20] [--report FILE] [--png FILE] [--alpha 1.5]\n"
               "  up TOPOLOGY.yaml [--detach] [--state DIR]       start every service as a local process\n"
               "  down TOPOLOGY.yaml | --state DIR                stop a detached cluster\n"
               "  watch TOPOLOGY.yaml | --target HOST:PORT [--count N] [--objects 10]   print the live global map\n"
               "  geofence set TOPOLOGY.yaml | --target HOST:PORT --name NAME --box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX\n"
               "  geofence query TOPOLOGY.yaml | --target HOST:PORT [--name NAME]   objects of the global map in the geofences\n"
               "  topology star|tree --edges K --source DIR [--base-port P] [--mode madc|baseline|ext] [--frames N] [--out FILE]\n"
               "  split --input SCAN --views K [--overlap-deg 10] --out DIR   cut a scan into virtual LiDARs\n";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "help") == 0) {
    usage();
    return argc < 2 ? 2 : 0;
  }
  const std::string command = argv[1];
  if (command == "cluster") return fogmap::cli::runCluster(argc, argv);
  if (command == "bench") return fogmap::cli::runBench(argc, argv);
  if (command == "up") return fogmap::cli::runUp(argc, argv);
  if (command == "down") return fogmap::cli::runDown(argc, argv);
  if (command == "topology") return fogmap::cli::runTopology(argc, argv);
  if (command == "split") return fogmap::cli::runSplit(argc, argv);
  if (command == "watch") return fogmap::cli::runWatch(argc, argv);
  if (command == "geofence") return fogmap::cli::runGeofence(argc, argv);
  if (command == "demo") return fogmap::cli::runDemo(argc, argv);
  std::cerr << "fogctl: unknown command '" << command << "'\n";
  usage();
  return 2;
}
