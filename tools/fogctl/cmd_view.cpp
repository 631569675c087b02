// fogctl view: the live map in a browser (view/): the root's global map and the tracker's tracks,
// pushed to a web page as they come.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>

#include "common/config/topology_parse.hpp"
#include "harness/launcher.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"
#include "view/view_runtime.hpp"

namespace fogmap::cli {
namespace {

using harness::installStopHandlers;
using harness::stopRequested;

constexpr const char* kViewUsage =
    "fogctl view TOPOLOGY.yaml [--port 8080] [--listen 127.0.0.1] [--geofences NAME=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX;...]";

int runView(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"port", "listen", "geofences", "max-pages", "identity", "cert", "key", "ca"}, {});
  if (!args) return fail(args.error());
  if (args->positional().size() != 1) return fail(invalidArgument(std::string("usage: ") + kViewUsage));
  auto topology = loadTopology(args->positional()[0]);
  if (!topology) return fail(topology.error());
  const auto port = args->getInt("port", 8080);
  if (!port || *port < 0 || *port > 65535) return fail(invalidArgument("--port must be a port number (0 to 65535; 0: any free one)"));
  installStopHandlers();
  auto view = startLiveView(*args, *topology, static_cast<std::uint16_t>(*port));
  if (!view) return fail(view.error());
  std::printf("fogctl view: %s; Ctrl-C stops\n", (*view)->url().c_str());
  std::fflush(stdout);
  while (!stopRequested()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  return 0;
}

}  // namespace

Expected<std::unique_ptr<view::ViewRuntime>> startLiveView(const Args& args, const TopologyConfig& topology, std::uint16_t port) {
  const auto root = rootConnection(args, kViewUsage, Role::kAggregator);
  if (!root) return root.error();
  std::optional<view::FeedTarget> tracker;
  if (std::any_of(topology.nodes.begin(), topology.nodes.end(), [](const NodeConfig& n) { return n.role == Role::kTracker; })) {
    const auto connection = rootConnection(args, kViewUsage, Role::kTracker);
    if (!connection) return connection.error();
    tracker = view::FeedTarget{connection->target, connection->credentials};
  }
  const auto max_pages = args.getInt("max-pages", 16);
  if (!max_pages || *max_pages < 1 || *max_pages > 256) return invalidArgument("--max-pages must be within 1 and 256");
  auto fences = view::parseFenceBoxes(args.get("geofences"));
  if (!fences) return fences.error();
  view::ViewOptions options;
  options.web.address = args.get("listen", "127.0.0.1");
  options.web.port = port;
  options.max_pages = static_cast<std::size_t>(*max_pages);
  options.max_message_bytes = topology.max_message_bytes;
  return view::ViewRuntime::start(view::viewConfigOf(topology, std::move(*fences)), view::FeedTarget{root->target, root->credentials},
                                  tracker, options);
}

Command viewCommand() {
  return {"view",
          "TOPOLOGY.yaml [--port 8080] [--listen 127.0.0.1]   the live map, tracks and health in a browser",
          std::string("usage: ") + kViewUsage +
              "\n"
              "                   [--max-pages 16] [--identity NAME | --cert FILE --key FILE --ca FILE]\n"
              "Serves a web page that shows, live, the root's global map (each object's ellipses seen from above, its\n"
              "oriented box and class), the tracker's tracks with their trails (when the topology has a tracker),\n"
              "the sensors, the geofences and whether they are occupied, and each node's state. The page is pushed\n"
              "every epoch (Server-Sent Events at /events; the view's counters at /metrics). When the root or the\n"
              "tracker goes away the page says so, and the view subscribes again until it is back.\n"
              "  --port P        the port (default 8080; 0: a free one, printed)\n"
              "  --listen ADDR   the IPv4 address to listen on, and nothing else (default 127.0.0.1)\n"
              "  --geofences G   geofences to draw, NAME=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX separated by ';' (as set with\n"
              "                  fogctl geofence set); their occupancy is computed on each global map as the root does\n"
              "  --max-pages N   pages served at once (default 16); one more is answered 503\n" +
              std::string(kTlsFlagsUsage),
          runView};
}

}  // namespace fogmap::cli
