// fogctl down: stops a cluster fogctl up --detach started, and only what it started.
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "harness/launcher.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::stopRecorded;

int runDown(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"state"}, {});
  if (!args) return fail(args.error());
  Expected<std::filesystem::path> state = invalidArgument("usage: fogctl down TOPOLOGY.yaml | --state DIR");
  if (args->has("state")) {
    state = absoluteDir(args->get("state"));
  } else if (args->positional().size() == 1) {
    const auto topology = loadTopology(args->positional()[0]);
    if (!topology) return fail(topology.error());
    state = stateDir(*args, args->positional()[0], *topology);
  }
  if (!state) return fail(state.error());
  const auto report = stopRecorded(*state, std::chrono::milliseconds(5000));
  if (!report) return fail(report.error());
  for (const auto& n : report->gone) {
    std::fprintf(stderr, "fogctl: pid %d (%s) has already exited\n", static_cast<int>(n.pid), n.name.c_str());
  }
  for (const auto& n : report->replaced) {
    std::fprintf(stderr, "fogctl: pid %d (%s) is no longer the service fogctl started; left alone\n", static_cast<int>(n.pid),
                 n.name.c_str());
  }
  std::printf("stopped %zu service(s) of the cluster recorded in %s\n", report->stopped.size(), state->c_str());
  return 0;
}

}  // namespace

Command downCommand() {
  return {"down",
          "TOPOLOGY.yaml | --state DIR                stop a detached cluster",
          "usage: fogctl down TOPOLOGY.yaml | --state DIR\n"
          "Stops a cluster started by fogctl up --detach. Only processes that are still the services fogctl\n"
          "started are signalled; records of processes that are gone or were replaced are reported and left alone.\n",
          runDown};
}

}  // namespace fogmap::cli
