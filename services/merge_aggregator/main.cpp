// merge-aggregator: the composition root. Reads the topology, builds the aggregator of its node
// (core, parent link, adapters, emitter: AggregatorProcess), serves it until SIGINT or SIGTERM and
// stops within ShutdownBudget::deadline (5 s) of the signal (docs/design.md "Delivery").
//   merge-aggregator --topology FILE --node NAME
#include "services/common/service_main.hpp"
#include "services/merge_aggregator/aggregator_process.hpp"

int main(int argc, char** argv) {
  const fogmap::ServiceSpec spec{fogmap::Role::kAggregator, "usage: merge-aggregator --topology FILE --node NAME\n"};
  return fogmap::runService(argc, argv, spec, [](fogmap::ServiceContext& context) {
    auto process = fogmap::AggregatorProcess::create(context);
    if (!process) return context.badConfig(context.topology_file.string() + ": " + process.error().message);
    context.serveMetrics();
    return fogmap::serveUntilStopped(context, (*process)->services(), (*process)->lifecycle());
  });
}
