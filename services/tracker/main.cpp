// tracker: the composition root. Reads the topology, builds the tracker of its node (core, adapter,
// LiDAR input, tick, metrics: TrackerProcess), serves it until SIGINT or SIGTERM and stops.
//   tracker --topology FILE --node NAME
#include "services/common/service_main.hpp"
#include "services/tracker/tracker_process.hpp"

int main(int argc, char** argv) {
  const fogmap::ServiceSpec spec{
      fogmap::Role::kTracker,
      "usage: tracker --topology FILE --node NAME\n"
      "Fuses the root's global maps (input: global_map) or the displacement centroids its edges stream\n"
      "(input: centroids; the edges whose displacement: section names it) with the detections of the\n"
      "tracker's cameras (the detection nodes whose parent it is) into tracks, served on\n"
      "TrackerService.Subscribe; settings in the node's tracker: section (input, centroid_merge_m,\n"
      "association paper|kalman, eps_sync_s, thresholds, track life cycle).\n"};
  return fogmap::runService(argc, argv, spec, [](fogmap::ServiceContext& context) {
    auto process = fogmap::TrackerProcess::create(context);
    if (!process) {
      context.log(process.error().message);
      return fogmap::kExitBadConfig;
    }
    context.serveMetrics();
    return fogmap::serveUntilStopped(context, (*process)->services(), (*process)->lifecycle());
  });
}
