// fogctl: the command-line front of fogmap. Dispatches to the commands (cmd_*.cpp), each of which
// owns its usage text.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "tools/fogctl/commands.hpp"

namespace {

using fogmap::cli::Command;

// In the order `fogctl --help` lists them.
const std::vector<Command>& commands() {
  using namespace fogmap::cli;
  static const std::vector<Command> all = {
      clusterCommand(), benchCommand(),    demoCommand(),   evalCommand(),    trackEvalCommand(), overlayCommand(),
      upCommand(),      downCommand(),     watchCommand(),  geofenceCommand(), faultsCommand(),   certsCommand(),
      composeCommand(), topologyCommand(), sceneCommand(),  splitCommand(),    trainClassifierCommand(), viewCommand(),
  };
  return all;
}

void usage(std::FILE* to) {
  std::fprintf(to, "usage: fogctl <command> [flags]\n");
  for (const auto& c : commands()) std::fprintf(to, "  %s %s\n", c.name.c_str(), c.synopsis.c_str());
  std::fprintf(to, "fogctl <command> --help (or fogctl help <command>) describes a command's flags.\n");
}

const Command* find(const std::string& name) {
  for (const auto& c : commands()) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

bool asksForHelp(int argc, char** argv) {
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  const std::string first = argv[1];
  if (first == "--help" || first == "-h" || first == "help") {
    if (first == "help" && argc > 2) {
      const Command* c = find(argv[2]);
      if (c == nullptr) {
        std::fprintf(stderr, "fogctl: unknown command '%s'\n", argv[2]);
        usage(stderr);
        return 2;
      }
      std::fputs(c->usage.c_str(), stdout);
      return 0;
    }
    usage(stdout);
    return 0;
  }
  const Command* command = find(first);
  if (command == nullptr) {
    std::fprintf(stderr, "fogctl: unknown command '%s'\n", first.c_str());
    usage(stderr);
    return 2;
  }
  if (asksForHelp(argc, argv)) {
    std::fputs(command->usage.c_str(), stdout);
    return 0;
  }
  try {
    return command->run(argc, argv);
  } catch (const std::exception& e) {
    // The commands return errors as values; this only keeps one that escapes from aborting.
    std::fprintf(stderr, "fogctl %s: %s\n", first.c_str(), e.what());
    return 1;
  }
}
