// fogctl faults: the fault harness (harness/faults.hpp) from the command line.
#include <chrono>
#include <fstream>
#include <iostream>

#include "common/config/topology.hpp"
#include "harness/faults.hpp"
#include "harness/launcher.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::FaultPlan;
using harness::FaultScenario;
using harness::StallMethod;
using harness::installStopHandlers;
using harness::loadStartableTopology;
using harness::parseScenario;
using harness::summary;
using harness::toJson;

int runFaults(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2,
                                {"scenario", "stall-by", "duration-s", "warmup-s", "seed", "kills", "downtime-s", "report", "state"},
                                {"no-oracle"});
  if (!args) return fail(args.error(), "fogctl faults");
  if (args->positional().size() != 1) return fail(invalidArgument("expected one topology file (see fogctl faults --help)"), "fogctl faults");
  const std::filesystem::path file = args->positional()[0];
  const auto topology = loadStartableTopology(file);
  if (!topology) return fail(topology.error(), "fogctl faults");

  FaultPlan plan;
  const auto scenario = parseScenario(args->get("scenario", "soak"));
  if (!scenario) {
    return fail(invalidArgument("--scenario must be soak, edge-crash, aggregator-crash or stall, not '" +
                                args->get("scenario") + "'"), "fogctl faults");
  }
  plan.scenario = *scenario;
  const auto duration = args->getDouble("duration-s", 60.0);
  const auto warmup = args->getDouble("warmup-s", 20.0);
  const auto seed = args->getInt("seed", 1);
  const auto kills = args->getInt("kills", 2);
  const auto downtime = args->getDouble("downtime-s", plan.scenario == FaultScenario::kStall ? 5.0 : 3.0);
  for (const auto* value : {&duration, &warmup, &downtime}) {
    if (!*value) return fail(value->error(), "fogctl faults");
  }
  if (!seed || !kills) return fail(!seed ? seed.error() : kills.error(), "fogctl faults");
  if (!(*duration >= 5.0 && *duration <= 24 * 3600.0)) return fail(invalidArgument("--duration-s must be in [5, 86400]"), "fogctl faults");
  if (!(*warmup >= 0.0 && *warmup < *duration)) return fail(invalidArgument("--warmup-s must be in [0, duration)"), "fogctl faults");
  if (!(*downtime > 0.0 && *downtime < *duration)) return fail(invalidArgument("--downtime-s must be in (0, duration)"), "fogctl faults");
  if (*seed < 0 || *kills < 0) return fail(invalidArgument("--seed and --kills must not be negative"), "fogctl faults");
  const auto millis = [](double s) { return std::chrono::milliseconds(static_cast<long>(s * 1000.0)); };
  plan.duration = millis(*duration);
  plan.warmup = millis(*warmup);
  plan.downtime = millis(*downtime);
  plan.seed = static_cast<std::uint64_t>(*seed);
  plan.edge_kills = static_cast<int>(*kills);
  plan.check_oracle = !args->has("no-oracle");
  const std::string stall_by = args->get("stall-by", "sigstop");
  if (stall_by != "sigstop" && stall_by != "netns") {
    return fail(invalidArgument("--stall-by must be sigstop or netns, not '" + stall_by + "'"), "fogctl faults");
  }
  plan.stall_method = stall_by == "netns" ? StallMethod::kNetns : StallMethod::kSigstop;

  installStopHandlers();
  const std::filesystem::path state = args->get("state", (file.parent_path() / ".fogmap" / "faults").string());
  const auto report = harness::runFaults(state, *topology, plan);
  if (!report) return fail(report.error(), "fogctl faults");
  std::cout << summary(*report);
  const std::filesystem::path json = args->get("report", (state / topology->name / "faults.json").string());
  std::ofstream out(json);
  out << toJson(*report);
  if (!out) return fail(ioError("cannot write " + json.string()), "fogctl faults");
  std::cout << "report: " << json.string() << "\n";
  return report->passed() ? 0 : 1;
}

}  // namespace

Command faultsCommand() {
  return {"faults",
          "TOPOLOGY.yaml --scenario soak|edge-crash|aggregator-crash|stall [--duration-s 60] [--seed 1] [--report FILE]",
          "usage: fogctl faults TOPOLOGY.yaml [--scenario soak|edge-crash|aggregator-crash|stall] [--duration-s 60]\n"
          "                     [--warmup-s 20] [--seed 1] [--kills 2] [--downtime-s S] [--report FILE] [--state DIR]\n"
          "                     [--stall-by sigstop|netns] [--no-oracle]\n"
          "Runs the topology as local processes under load, injects a fault at seeded times, and checks the\n"
          "root's global maps: every map an edge's parent acknowledged reaches the root, none is applied twice,\n"
          "every epoch is published, every global map equals the specification over its contributing nodes\n"
          "(mode madc), and the fault's own bounds. Exits 0 when every check passes, 1 otherwise.\n"
          "  --scenario S     soak (no fault), edge-crash (kill -9 of --kills edges, restarted after --downtime-s),\n"
          "                   aggregator-crash (kill -9 of one non-root aggregator, restarted after --downtime-s),\n"
          "                   stall (SIGSTOP of one non-root aggregator for --downtime-s, default 5)\n"
          "  --stall-by M     sigstop (default), or netns: the aggregator runs in a network namespace of its\n"
          "                   own and every packet of it is dropped with iptables (root, ip and iptables)\n"
          "  --duration-s S   how long the load runs (default 60); --warmup-s: RSS growth is measured after it\n"
          "  --seed N         chooses the victims and the times (default 1)\n"
          "  --report FILE    the JSON report (default STATE/NAME/faults.json)\n"
          "  --state DIR      logs, journals and the report (default .fogmap/faults next to the topology)\n"
          "  --no-oracle      skip the comparison with the specification (it recomputes every edge's maps)\n"
          "The long soak: fogctl topology tree --edges 8 --source data/kitti_raw_seq_a --out tree-8.yaml &&\n"
          "               fogctl faults tree-8.yaml --scenario soak --duration-s 600 --warmup-s 60\n",
          runFaults};
}

}  // namespace fogmap::cli
