// edge-cluster: replays one sensor's scans, clusters them at the edge (MAD-C, baseline or ext) and
// pushes what the mode ships up the stream to its parent aggregator; with a displacement section,
// also streams each scan's displacement centroids to its tracker. Composition root only: the
// process's parts and how it ends are EdgeProcess's, the replay loop EdgeRunner's.
#include "services/common/service_main.hpp"
#include "services/edge_cluster/edge_process.hpp"
#include "common/config/displacement_node.hpp"

int main(int argc, char** argv) {
  const fogmap::ServiceSpec spec{
      fogmap::Role::kEdge,
      "usage: edge-cluster --topology FILE --node NAME [--journal FILE]\n"
      "  --journal FILE  record how each upload ended (fault tests compare it with the root's maps)\n",
      {"journal"}};
  return fogmap::runService(argc, argv, spec, [](fogmap::ServiceContext& context) {
    auto process = fogmap::EdgeProcess::create(context);
    if (!process) return context.badConfig(process.error().message);
    context.serveMetrics();
    return (*process)->run();
  });
}
