// fogctl: the command-line front of fogmap.
#include <cstring>
#include <iostream>
#include <string>

#include "tools/fogctl/commands.hpp"

namespace {

void usage() {
  std::cerr << "usage: fogctl <command> [flags]\n"
               "  cluster --input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--method fogmap|pcl] [--remove-ground]\n"
               "  bench clustering --input SCAN [--eps 0.35] [--min-points 10] [--remove-ground] [--repeat 5] [--json]\n";
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
  std::cerr << "fogctl: unknown command '" << command << "'\n";
  usage();
  return 2;
}
