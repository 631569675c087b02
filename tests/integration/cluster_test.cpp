// Integration: real edge-cluster and merge-aggregator processes on 127.0.0.1, replaying the
// bundled real KITTI frames; the test subscribes to the root like any client.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <vector>

#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/config/topology_presets.hpp"
#include "common/geometry/geofence.hpp"
#include "common/geometry/map.hpp"
#include "harness/cluster_run.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/shell.hpp"
#include "tests/support/cluster_control.hpp"
#include "tests/support/eventually.hpp"
#include "tests/support/free_ports.hpp"
#include "harness/launcher.hpp"
#include "services/common/endpoint.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/source_dir.hpp"
#include "tests/support/time_scale.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using harness::RunOptions;
using harness::RunResult;

using test_support::keptDir;
using test_support::kittiSequenceDir;
constexpr std::size_t kScans = 5;  // bundled frames: epoch e replays scan e mod 5

// A topology over the bundled frames whose ports are chosen free at run time.
TopologyConfig topology(const std::string& shape, int edges, Mode mode, std::uint64_t frames) {
  constexpr int kAnyBasePort = 40000;  // replaced by free ports below
  TopologyConfig t = shape == "star" ? makeStarTopology(edges, kittiSequenceDir(), kAnyBasePort)
                                     : makeTreeTopology(edges, kittiSequenceDir(), kAnyBasePort);
  test_support::useFreePorts(t);
  t.mode = mode;
  t.name = std::string(modeName(mode)) + "-" + t.name;
  t.deadline_ms = 500.0;  // generous: a loaded CI machine must not turn slow epochs into partial ones
  for (auto& n : t.nodes) {
    if (n.sensor) n.sensor->frames = frames;
  }
  return t;
}

// The same map with every ellipsoid's frame replaced: maps of different epochs that replayed the
// same scan are then comparable.
Map withFrame(const Map& map, std::uint64_t frame) {
  Map out = map;
  for (auto& o : out.objects) {
    for (auto& e : o.ellipsoids) e.id.frame = frame;
  }
  return out;
}

// `t` on a schedule stretched by the test time scale (tests/support/time_scale.hpp): period,
// deadline and sensor rates, for the tests whose oracle needs complete epochs.
TopologyConfig stretched(TopologyConfig t) {
  const double scale = test_support::testTimeScale();
  t.period_ms *= scale;
  t.deadline_ms *= scale;
  for (auto& n : t.nodes) {
    if (n.sensor) n.sensor->rate_hz /= scale;
  }
  return t;
}

std::chrono::milliseconds scaled(std::chrono::milliseconds timeout) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(timeout * test_support::testTimeScale());
}

// Runs the cluster and checks every complete epoch's global map against MERGE of the local maps
// recomputed in-process (as the parent decodes them). Returns the global maps by scan index.
std::map<std::size_t, Map> runAndCheckAgainstInProcessMerge(const TopologyConfig& t, const std::string& name) {
  RunOptions options;
  options.frames = 1000;  // everything the edges produce
  options.timeout = 120s;
  options.timeout = scaled(options.timeout);
  const TopologyConfig run_topology = stretched(t);
  const auto run = harness::runCluster(keptDir(name), run_topology, options);
  EXPECT_TRUE(run.ok()) << (run.ok() ? "" : run.error().message);
  if (!run.ok()) return {};
  const auto epochs = completeEpochs(*run);
  EXPECT_GE(epochs.size(), 3U) << name << ": too few complete epochs (" << run->epochs.size() << " published)";
  const auto views = harness::recomputeEdges(run_topology, epochs);
  EXPECT_TRUE(views.ok()) << (views.ok() ? "" : views.error().message);
  if (!views.ok()) return {};
  std::map<std::size_t, Map> by_scan;
  for (const auto e : epochs) {
    const GlobalMapMessage& global = run->epochs.at(e);
    auto published = throughGlobalWire(mergeAll(views->at(e).local_maps).map);
    EXPECT_TRUE(published.ok()) << published.error().message;
    if (!published.ok()) return {};
    const Map& expected = *published;
    EXPECT_GT(expected.objects.size(), 20U);
    EXPECT_EQ(global.map, expected) << name << " epoch " << e << ": " << global.map.objects.size() << " objects, expected "
                                    << expected.objects.size();
    EXPECT_EQ(global.header.contributing_nodes.size(), views->at(e).local_maps.size());
    by_scan[e % kScans] = withFrame(global.map, e % kScans);
  }
  return by_scan;
}

TEST(Cluster, StarOfThreeGlobalMapEqualsInProcessMerge) {
  runAndCheckAgainstInProcessMerge(topology("star", 3, Mode::kMadc, 30), "star3");
}

TEST(Cluster, StarAndTreeOfSevenGiveTheSameGlobalMap) {
  // Seven edges pre-processing a KITTI scan each at 10 Hz need about all of 2 cores: an edge that
  // misses its period skips an epoch (by design), and with seven of them few epochs stay complete.
  // At 5 Hz the same scans leave room (epoch e still replays scan e mod 5).
  const auto halfRate = [](TopologyConfig t) {
    t.period_ms = 200.0;
    for (auto& n : t.nodes) {
      if (n.sensor) n.sensor->rate_hz = 5.0;
    }
    return t;
  };
  const auto tree = runAndCheckAgainstInProcessMerge(halfRate(topology("tree", 7, Mode::kMadc, 30)), "tree7");
  const auto star = runAndCheckAgainstInProcessMerge(halfRate(topology("star", 7, Mode::kMadc, 30)), "star7");
  std::size_t compared = 0;
  for (const auto& [scan, map] : tree) {
    const auto it = star.find(scan);
    if (it == star.end()) continue;
    EXPECT_EQ(map, it->second) << "scan " << scan;
    ++compared;
  }
  EXPECT_GE(compared, 2U) << "star and tree shared too few complete scans";
}

TEST(Cluster, MadcAgreesWithBaselineRandIndexAtLeast095) {
  RunOptions options;
  options.frames = 1000;  // everything the edges produce
  options.timeout = 120s;
  options.timeout = scaled(options.timeout);
  const auto madc = harness::runCluster(keptDir("ri-madc"), stretched(topology("star", 3, Mode::kMadc, 20)), options);
  ASSERT_TRUE(madc.ok()) << madc.error().message;
  options.point_labels = true;
  const auto baseline = harness::runCluster(keptDir("ri-base"), stretched(topology("star", 3, Mode::kBaseline, 20)), options);
  ASSERT_TRUE(baseline.ok()) << baseline.error().message;
  std::map<std::size_t, const GlobalMapMessage*> baseline_by_scan;
  for (const auto& [e, g] : baseline->epochs) {
    if (g.header.missing_nodes.empty()) baseline_by_scan[e % kScans] = &g;
  }
  std::vector<std::uint64_t> epochs;
  for (const auto e : completeEpochs(*madc)) {
    if (baseline_by_scan.count(e % kScans) > 0) epochs.push_back(e);
  }
  ASSERT_GE(epochs.size(), 3U);
  const auto views = harness::recomputeEdges(stretched(topology("star", 3, Mode::kMadc, 10)), epochs);
  ASSERT_TRUE(views.ok()) << views.error().message;
  for (const auto e : epochs) {
    const auto a = harness::accuracy(madc->epochs.at(e), *baseline_by_scan.at(e % kScans), views->at(e));
    ASSERT_TRUE(a.ok) << a.problem;
    std::printf("epoch %lu (scan %zu): Rand index %.4f (ARI %.4f) over local clusters, %.4f over points\n",
                static_cast<unsigned long>(e), static_cast<std::size_t>(e % kScans), a.clusters.rand_index,
                a.clusters.adjusted_rand_index, a.points.rand_index);
    // The paper's measure (local clusters as elements) must reach 0.95. Over points, pairs inside
    // the few largest objects dominate, so one merged or split wall weighs heavily: a floor only.
    EXPECT_GE(a.clusters.rand_index, 0.95);
    EXPECT_GE(a.points.rand_index, 0.90);
  }
  // And the savings the system exists for.
  const double madc_bytes = madc->bytes_moved / static_cast<double>(madc->epochs.size());
  const double baseline_bytes = baseline->bytes_moved / static_cast<double>(baseline->epochs.size());
  std::printf("bytes per frame: MAD-C %.0f, baseline %.0f (%.0fx)\n", madc_bytes, baseline_bytes, baseline_bytes / madc_bytes);
  EXPECT_GT(baseline_bytes, 20.0 * madc_bytes);
}

bool lists(const std::vector<std::uint32_t>& nodes, std::uint32_t node) {
  return std::find(nodes.begin(), nodes.end(), node) != nodes.end();
}

TEST(Cluster, KillingAnEdgeLeavesTheOthersFlowingAndListsItMissing) {
  // What the root promises once an edge dies: it goes on publishing every epoch; every epoch that
  // began after the death (for which the dead edge cannot have sent anything) lists it missing;
  // the other edges go on contributing. Which epochs a loaded machine gets in on time is not part
  // of it: the test waits for what it needs to see instead of counting epochs in a time budget.
  TopologyConfig t = topology("star", 3, Mode::kMadc, 0);
  test_support::replayUntilStopped(t);  // the edges go on until the test has seen enough
  constexpr std::uint32_t kKilled = 2;  // edge-2
  const std::vector<std::uint32_t> survivors{1, 3};
  constexpr std::size_t kEpochsEach = 5;  // epochs after the death each survivor is seen in
  const auto schedule = EpochSchedule::create(t.period_ms, t.deadline_ms);
  ASSERT_TRUE(schedule.ok());
  const auto has_both_survivors = [&](const GlobalMapMessage& g) {
    return std::all_of(survivors.begin(), survivors.end(), [&](std::uint32_t s) { return lists(g.header.contributing_nodes, s); });
  };
  std::uint64_t death_epoch = 0;  // the epoch in which edge-2 was gone for certain
  std::uint64_t last_seen = 0;    // the last epoch the test's subscription waited for
  RunOptions options;
  options.frames = std::numeric_limits<std::uint64_t>::max();  // every epoch until the edges are stopped
  options.timeout = 120s;
  const auto run = harness::runCluster(keptDir("kill"), t, options, [&](const harness::Cluster& cluster) {
    const test_support::EdgesStopper stop_edges(cluster, t);  // once the test has seen enough
    test_support::RootSubscription published(t, options.timeout);
    ASSERT_TRUE(published.readUntil([&](const GlobalMapMessage& g) { return test_support::everySensor(t, g); }).has_value())
        << "no global map with every edge before the kill";
    const auto edge = std::find_if(cluster.nodes.begin(), cluster.nodes.end(),
                                   [](const harness::RunningNode& n) { return n.name == "edge-2"; });
    ASSERT_NE(edge, cluster.nodes.end());
    ASSERT_EQ(::kill(edge->pid, SIGKILL), 0);
    // Reaped: it sends nothing more. An edge ships epoch k only once k has begun, so no later
    // epoch can hold its data.
    ASSERT_TRUE(test_support::eventually([&] { return !harness::isRunning(edge->pid); }));
    death_epoch = schedule->epochAt(systemNowNs());

    // The root notices, and the survivors keep flowing: each of them is seen in epochs after the
    // death, and at least once both together.
    ASSERT_TRUE(published.readUntil([&](const GlobalMapMessage& g) {
      return g.header.epoch > death_epoch && lists(g.header.missing_nodes, kKilled);
    }).has_value()) << "the root never listed the killed edge missing";
    std::map<std::uint32_t, std::size_t> seen;
    bool both = false;
    const auto flowing = published.readUntil([&](const GlobalMapMessage& g) {
      for (const std::uint32_t s : survivors) seen[s] += lists(g.header.contributing_nodes, s) ? 1 : 0;
      both = both || has_both_survivors(g);
      return both && std::all_of(survivors.begin(), survivors.end(), [&](std::uint32_t s) { return seen[s] >= kEpochsEach; });
    });
    ASSERT_TRUE(flowing.has_value()) << "the surviving edges stopped flowing: edge-1 seen in " << seen[1]
                                     << " epochs, edge-3 in " << seen[3];
    last_seen = flowing->header.epoch;
  });
  ASSERT_TRUE(run.ok()) << run.error().message;
  ASSERT_GT(death_epoch, 0U);
  ASSERT_GT(last_seen, death_epoch);

  // Every epoch published, none skipped (late ones come flagged, never left out), up to at least
  // the last one the test waited for.
  ASSERT_FALSE(run->epochs.empty());
  const std::uint64_t first = run->epochs.begin()->first;
  const std::uint64_t last = run->epochs.rbegin()->first;
  EXPECT_LT(first, death_epoch);
  EXPECT_GE(last, last_seen);
  EXPECT_EQ(run->epochs.size(), last - first + 1) << "epochs were skipped between " << first << " and " << last;

  std::map<std::uint32_t, std::size_t> contributed;  // epochs after the death, per survivor
  std::size_t with_both = 0;
  for (const auto& [e, g] : run->epochs) {
    if (e <= death_epoch) continue;
    EXPECT_TRUE(lists(g.header.missing_nodes, kKilled)) << "epoch " << e << " does not list edge-2 missing";
    EXPECT_FALSE(lists(g.header.contributing_nodes, kKilled)) << "epoch " << e << " has data of the dead edge-2";
    for (const std::uint32_t s : survivors) contributed[s] += lists(g.header.contributing_nodes, s) ? 1 : 0;
    if (!has_both_survivors(g)) continue;
    ++with_both;
    EXPECT_GT(g.map.objects.size(), 10U) << "epoch " << e;
  }
  for (const std::uint32_t s : survivors) {
    EXPECT_GE(contributed[s], kEpochsEach) << "edge-" << s << " contributed to too few epochs after the kill";
  }
  EXPECT_GE(with_both, 1U);
  std::printf("edge-2 gone in epoch %lu; epochs %lu..%lu after it: edge-1 in %zu, edge-3 in %zu, both in %zu\n",
              static_cast<unsigned long>(death_epoch), static_cast<unsigned long>(death_epoch + 1),
              static_cast<unsigned long>(last), contributed[1], contributed[3], with_both);
}

std::pair<int, std::string> run(const std::string& command) { return test_support::runCommand(command); }

// fogctl geofence against a running root: the intrusions it prints are exactly those of the
// global map of the epoch it names, as the root published it, recomputed in-process.
TEST(Cluster, FogctlGeofenceReportsTheIntrusionsOfThePublishedGlobalMap) {
  // Stretched: the latest map a query names must be one the slowed edges (under a sanitizer) filled.
  TopologyConfig t = stretched(topology("star", 3, Mode::kMadc, 40));
  test_support::replayUntilStopped(t);  // the subscriber collects until the queries are done
  const std::string target = endpoint(t.root()->host, t.root()->port);
  const std::string fogctl = (harness::binaryDir() / "fogctl").string() + " geofence ";
  const Geofence fence = boxGeofence("front", {0, -4, -3}, {20, 4, 3});
  std::pair<int, std::string> set, query, unknown;
  RunOptions options;
  options.frames = std::numeric_limits<std::uint64_t>::max();
  options.timeout = scaled(120s);
  const auto result = harness::runCluster(keptDir("geofence"), t, options, [&](const harness::Cluster& cluster) {
    const test_support::EdgesStopper stop_edges(cluster, t);  // once the queries are done
    // The queries name the root's latest map: one with every edge's objects by now.
    test_support::RootSubscription published(t, options.timeout);
    ASSERT_TRUE(published.readUntil([&](const GlobalMapMessage& g) { return test_support::everySensor(t, g); }).has_value())
        << "no global map with every edge";
    set = run(fogctl + "set --target " + target + " --name front --box 0,-4,-3,20,4,3");
    query = run(fogctl + "query --target " + target + " --name front");
    unknown = run(fogctl + "query --target " + target + " --name nowhere");
  });
  ASSERT_TRUE(result.ok()) << result.error().message;
  EXPECT_EQ(set.first, 0) << set.second;
  ASSERT_EQ(query.first, 0) << query.second;
  EXPECT_EQ(unknown.first, 1) << unknown.second;
  EXPECT_NE(unknown.second.find("no geofence named 'nowhere'"), std::string::npos) << unknown.second;

  std::istringstream lines(query.second);
  std::string line;
  unsigned long epoch = 0;
  ASSERT_TRUE(std::getline(lines, line));
  ASSERT_EQ(std::sscanf(line.c_str(), "epoch %lu:", &epoch), 1) << query.second;
  std::vector<std::pair<std::size_t, std::string>> printed;
  while (std::getline(lines, line)) {
    unsigned index = 0;
    char containment[16] = {};
    if (std::sscanf(line.c_str(), "front object %u %15s", &index, containment) == 2) printed.emplace_back(index, containment);
  }
  ASSERT_EQ(result->epochs.count(epoch), 1U)
      << "the subscriber did not receive epoch " << epoch << "; it received " << result->epochs.size()
      << " epochs from " << (result->epochs.empty() ? 0 : result->epochs.begin()->first) << " to "
      << (result->epochs.empty() ? 0 : result->epochs.rbegin()->first);
  std::vector<std::pair<std::size_t, std::string>> expected;
  for (const auto& hit : intrusions(result->epochs.at(epoch).map, fence)) {
    expected.emplace_back(hit.object_index, containmentName(hit.containment));
  }
  EXPECT_GT(expected.size(), 3U);
  EXPECT_EQ(printed, expected) << query.second;

  // Bad flags are usage errors, before any call.
  EXPECT_EQ(run(fogctl + "set --target " + target + " --name x --box 1,2,3").first, 2);
  EXPECT_EQ(run(fogctl + "set --target " + target + " --name x --box 1,2,3,0,5,6").first, 2);
  EXPECT_EQ(run(fogctl + "set --target " + target + " --name x --box 1,2,3,4,5,six").first, 2);
}

}  // namespace
}  // namespace fogmap
