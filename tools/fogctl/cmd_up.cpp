// fogctl up: every service of a topology as a local process, checked before it starts.
#include <chrono>
#include <memory>
#include <optional>
#include <cstdio>
#include <string>
#include <thread>

#include "common/config/topology.hpp"
#include "harness/launcher.hpp"
#include "view/view_runtime.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::PlannedNode;
using harness::allRunning;
using harness::installStopHandlers;
using harness::loadStartableTopology;
using harness::planCluster;
using harness::startCluster;
using harness::stopCluster;
using harness::stopRequested;

// A word the shell reads back unchanged: as is when it is plain, else in single quotes.
std::string shellWord(const std::string& word) {
  const bool plain = !word.empty() && word.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                                             "0123456789_./:=@%+,-") == std::string::npos;
  if (plain) return word;
  std::string quoted = "'";
  for (const char c : word) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

int runUp(int argc, char** argv) {
  const std::string usage = "usage: fogctl up TOPOLOGY.yaml [--detach] [--state DIR] [--timeout-s 30] [--dry-run] [--view PORT]";
  const auto args = Args::parse(argc, argv, 2, {"state", "timeout-s", "view", "listen", "geofences"}, {"detach", "dry-run"});
  if (!args) return fail(args.error());
  if (args->positional().size() != 1) return fail(invalidArgument(usage));
  const std::filesystem::path file = args->positional()[0];
  const auto topology = loadStartableTopology(file);
  if (!topology) return fail(topology.error());
  const auto timeout_s = args->getDouble("timeout-s", 30.0);
  if (!timeout_s) return fail(timeout_s.error());
  if (!(*timeout_s > 0.0 && *timeout_s <= 24 * 3600.0)) return fail(invalidArgument("--timeout-s must be in (0, 86400]"));
  std::optional<std::uint16_t> view_port;
  if (args->has("view")) {
    const auto port = args->getInt("view", 0);
    if (!port || *port < 0 || *port > 65535) return fail(invalidArgument("--view must be a port number (0: any free one)"));
    if (args->has("detach")) {
      return fail(invalidArgument("--view serves the page while fogctl up runs: without --detach, or start "
                                  "`fogctl view TOPOLOGY.yaml` beside a detached cluster"));
    }
    view_port = static_cast<std::uint16_t>(*port);
  } else if (args->has("listen") || args->has("geofences")) {
    return fail(invalidArgument("--listen and --geofences go with --view"));
  }
  const auto state = stateDir(*args, file, *topology);
  if (!state) return fail(state.error());
  const auto plan = planCluster(file, *topology, *state);
  if (!plan) return fail(plan.error());
  if (args->has("dry-run")) {
    for (const PlannedNode& node : *plan) {
      std::string command;
      for (const std::string& word : node.command) {
        if (!command.empty()) command += ' ';
        command += shellWord(word);
      }
      std::printf("would start %s (%s): %s\n", node.name.c_str(), roleName(node.role), command.c_str());
    }
    std::printf("cluster '%s': %zu services, mode %s, %s; logs would go to %s; nothing started\n", topology->name.c_str(),
                plan->size(), modeName(topology->mode), topology->tls ? "mutual TLS" : "plaintext", (*state / "logs").c_str());
    return 0;
  }
  installStopHandlers();
  auto cluster = startCluster(file, *topology, *state, std::chrono::milliseconds(static_cast<long>(*timeout_s * 1000)));
  if (!cluster) return fail(cluster.error());
  std::printf("%-14s %-11s %-22s %-8s %s\n", "node", "role", "listen", "metrics", "parent");
  for (const auto& n : topology->nodes) {
    const std::string listen = n.port ? n.host + ":" + std::to_string(n.port) : "-";
    std::printf("%-14s %-11s %-22s %-8u %s\n", n.name.c_str(), roleName(n.role), listen.c_str(),
                n.metrics_port, n.parent.empty() ? (n.role == Role::kAggregator ? "(root)" : "-") : n.parent.c_str());
  }
  std::printf("cluster '%s' is up (%zu services, mode %s, %s); logs in %s\n", topology->name.c_str(), topology->nodes.size(),
              modeName(topology->mode), topology->tls ? "mutual TLS" : "plaintext", (*state / "logs").c_str());
  if (args->has("detach")) {
    std::printf("stop it with: fogctl down --state %s\n", shellWord(state->string()).c_str());
    return 0;
  }
  std::unique_ptr<view::ViewRuntime> view;
  if (view_port) {
    auto started = startLiveView(*args, *topology, *view_port);
    if (!started) {
      stopCluster(*cluster, std::chrono::milliseconds(5000));
      return fail(started.error());
    }
    view = std::move(*started);
    std::printf("the live view: %s\n", view->url().c_str());
  }
  std::printf("Ctrl-C stops the cluster\n");
  while (!stopRequested() && allRunning(*cluster)) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  if (!allRunning(*cluster)) std::fprintf(stderr, "fogctl: a service exited; stopping the cluster (see %s)\n", (*state / "logs").c_str());
  view.reset();  // its pages learn the end from the closed stream, not from a root that went away
  stopCluster(*cluster, std::chrono::milliseconds(5000));
  std::printf("cluster '%s' stopped\n", topology->name.c_str());
  return 0;
}

}  // namespace

Command upCommand() {
  return {"up",
          "TOPOLOGY.yaml [--detach] [--state DIR] [--dry-run]   start every service as a local process",
          "usage: fogctl up TOPOLOGY.yaml [--detach] [--state DIR] [--timeout-s 30] [--dry-run]\n"
          "                 [--view PORT [--listen 127.0.0.1] [--geofences G]]\n"
          "Starts every service of the topology as a local process and waits until each serves /metrics.\n"
          "First checks what each service checks before it starts (every camera's detector settings and\n"
          "model files, every file a node reads; not the TLS files) and refuses the topology naming the node\n"
          "and the field.\n"
          "  --dry-run      check, and print the command of every service it would start and where its log\n"
          "                 would go; start, create and write nothing\n"
          "  --detach       leave the cluster running and print the command that stops it\n"
          "  --state DIR    where the pids and logs go (default: .fogmap/NAME next to the topology file)\n"
          "  --timeout-s S  how long the services may take to start (default 30)\n"
          "  --view PORT    also serve the live view (fogctl view) on 127.0.0.1:PORT (0: a free one, printed)\n"
          "                 while the cluster runs; --listen ADDR and --geofences G as fogctl view takes them\n",
          runUp};
}

}  // namespace fogmap::cli
