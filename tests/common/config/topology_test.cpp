#include "common/config/camera_node.hpp"
#include "common/config/displacement_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/config/tracker_node.hpp"
#include "tests/support/source_dir.hpp"

#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace fogmap {
namespace {

namespace fs = std::filesystem;

using test_support::kSourceDir;

// Field-by-field equality of everything the services read from a topology.
void expectSameTopology(const TopologyConfig& a, const TopologyConfig& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.mode, b.mode);
  EXPECT_EQ(a.baseline_ships_raw, b.baseline_ships_raw);
  EXPECT_DOUBLE_EQ(a.deadline_ms, b.deadline_ms);
  EXPECT_DOUBLE_EQ(a.period_ms, b.period_ms);
  EXPECT_EQ(a.max_message_bytes, b.max_message_bytes);
  EXPECT_EQ(a.max_scan_bytes, b.max_scan_bytes);
  EXPECT_EQ(a.admission, b.admission);
  EXPECT_DOUBLE_EQ(a.madc.clustering.eps_m, b.madc.clustering.eps_m);
  EXPECT_EQ(a.madc.clustering.min_points, b.madc.clustering.min_points);
  EXPECT_EQ(a.madc.clustering.threads, b.madc.clustering.threads);
  EXPECT_EQ(a.madc.fragment_min_points, b.madc.fragment_min_points);
  EXPECT_EQ(a.objects, b.objects);
  EXPECT_DOUBLE_EQ(a.madc.alpha, b.madc.alpha);
  EXPECT_DOUBLE_EQ(a.madc.alpha_max, b.madc.alpha_max);
  ASSERT_EQ(a.preprocess.crop.has_value(), b.preprocess.crop.has_value());
  if (a.preprocess.crop) {
    EXPECT_EQ(a.preprocess.crop->min_m, b.preprocess.crop->min_m);
    EXPECT_EQ(a.preprocess.crop->max_m, b.preprocess.crop->max_m);
  }
  EXPECT_EQ(a.preprocess.voxel_leaf_m, b.preprocess.voxel_leaf_m);
  ASSERT_EQ(a.preprocess.ground.has_value(), b.preprocess.ground.has_value());
  if (a.preprocess.ground) {
    EXPECT_DOUBLE_EQ(a.preprocess.ground->distance_threshold_m, b.preprocess.ground->distance_threshold_m);
    EXPECT_DOUBLE_EQ(a.preprocess.ground->max_tilt_deg, b.preprocess.ground->max_tilt_deg);
    EXPECT_EQ(a.preprocess.ground->ground_z_hint_m, b.preprocess.ground->ground_z_hint_m);
  }
  ASSERT_EQ(a.tls.has_value(), b.tls.has_value());
  if (a.tls) {
    EXPECT_EQ(a.tls->ca, b.tls->ca);
    EXPECT_EQ(a.tls->cert_dir, b.tls->cert_dir);
    EXPECT_EQ(a.tls->geofence_clients, b.tls->geofence_clients);
  }
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  for (std::size_t i = 0; i < a.nodes.size(); ++i) {
    const NodeConfig& x = a.nodes[i];
    const NodeConfig& y = b.nodes[i];
    SCOPED_TRACE("node " + x.name);
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.role, y.role);
    EXPECT_EQ(x.parent, y.parent);
    EXPECT_EQ(x.host, y.host);
    EXPECT_EQ(x.port, y.port);
    EXPECT_EQ(x.metrics_port, y.metrics_port);
    ASSERT_EQ(x.tls.has_value(), y.tls.has_value());
    if (x.tls) {
      EXPECT_EQ(x.tls->cert, y.tls->cert);
      EXPECT_EQ(x.tls->key, y.tls->key);
    }
    ASSERT_EQ(x.tracker.has_value(), y.tracker.has_value());
    if (x.tracker) {
      EXPECT_EQ(x.tracker->input, y.tracker->input);
      EXPECT_DOUBLE_EQ(x.tracker->centroid_merge_m, y.tracker->centroid_merge_m);
      EXPECT_DOUBLE_EQ(x.tracker->visible_side_max_radius_m, y.tracker->visible_side_max_radius_m);
      EXPECT_EQ(x.tracker->tracking.association, y.tracker->tracking.association);
      EXPECT_DOUBLE_EQ(x.tracker->tracking.rho_overlay_m, y.tracker->tracking.rho_overlay_m);
      EXPECT_EQ(x.tracker->tracking.confirm_hits, y.tracker->tracking.confirm_hits);
      EXPECT_DOUBLE_EQ(x.tracker->tracking.track_timeout_s, y.tracker->tracking.track_timeout_s);
      EXPECT_DOUBLE_EQ(x.tracker->tracking.publish_lost_s, y.tracker->tracking.publish_lost_s);
    }
    ASSERT_EQ(x.displacement.has_value(), y.displacement.has_value());
    if (x.displacement) {
      EXPECT_EQ(x.displacement->tracker, y.displacement->tracker);
      EXPECT_EQ(x.displacement->params, y.displacement->params);
    }
    ASSERT_EQ(x.sensor.has_value(), y.sensor.has_value());
    if (!x.sensor) continue;
    EXPECT_EQ(x.sensor->source.lexically_normal(), y.sensor->source.lexically_normal());
    EXPECT_EQ(x.sensor->scene.lexically_normal(), y.sensor->scene.lexically_normal());
    EXPECT_EQ(x.sensor->lidar, y.sensor->lidar);
    EXPECT_DOUBLE_EQ(x.sensor->rate_hz, y.sensor->rate_hz);
    EXPECT_EQ(x.sensor->loop, y.sensor->loop);
    EXPECT_EQ(x.sensor->frames, y.sensor->frames);
    EXPECT_EQ(x.sensor->clustering, y.sensor->clustering);
    EXPECT_EQ(x.sensor->model, y.sensor->model);
    ASSERT_EQ(x.sensor->split.has_value(), y.sensor->split.has_value());
    if (x.sensor->split) {
      EXPECT_EQ(x.sensor->split->views, y.sensor->split->views);
      EXPECT_EQ(x.sensor->split->index, y.sensor->split->index);
      EXPECT_DOUBLE_EQ(x.sensor->split->overlap_deg, y.sensor->split->overlap_deg);
    }
    EXPECT_TRUE(x.sensor->pose.isApprox(y.sensor->pose, 1e-9)) << x.sensor->pose.matrix() << "\n" << y.sensor->pose.matrix();
  }
}

// Non-default values everywhere, so a field that toYaml or the parser drops shows up.
void customize(TopologyConfig& t) {
  t.mode = Mode::kExt;
  t.deadline_ms = 45.5;
  t.period_ms = 50.0;
  t.max_message_bytes = 8U << 20;
  t.max_scan_bytes = 3U << 20;
  t.admission.window_periods = 2.5;
  t.admission.world_extent_m = 750.0;
  t.admission.max_ellipsoids_per_map = 1234;
  t.admission.max_map_bytes = 1U << 20;
  t.admission.min_eigenvalue_m2 = 1e-8;
  t.admission.max_eigenvalue_m2 = 2.5e5;
  t.admission.max_condition = 1e9;
  t.madc.clustering.eps_m = 0.55;
  t.madc.clustering.min_points = 7;
  t.madc.clustering.threads = 4;
  t.madc.fragment_min_points = 3;
  t.madc.alpha = 2.25;
  t.madc.alpha_max = 2.75;
  t.objects.boxes = true;
  t.objects.classifier = "/models/forest.yml.gz";
  t.preprocess.voxel_leaf_m = 0.125;
  t.preprocess.ground->distance_threshold_m = 0.3;
  t.preprocess.ground->max_tilt_deg = 20.0;
  auto& edge = t.nodes.back();
  edge.host = "10.0.0.7";
  edge.sensor->rate_hz = 5.0;
  edge.sensor->loop = false;
  edge.sensor->frames = 42;
  edge.sensor->pose.translation() = Eigen::Vector3d(1.5, -2.0, 0.25);
  edge.sensor->pose.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

TEST(Topology, StarRoundTripsThroughYaml) {
  TopologyConfig star = makeStarTopology(4, "scans", 51000);
  customize(star);
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(star), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  expectSameTopology(*parsed, star);
  EXPECT_EQ(parsed->root()->name, "sink");
  EXPECT_EQ(parsed->children("sink").size(), 4U);
  EXPECT_EQ(parsed->sensorsBelow("sink"), (std::vector<std::uint32_t>{1, 2, 3, 4}));
}

TEST(Topology, ABaselineThatShipsWholeScansRoundTripsAndOnlyProcessedOrRawIsAccepted) {
  TopologyConfig star = makeStarTopology(2, "scans", 51000);
  star.mode = Mode::kBaseline;
  star.baseline_ships_raw = true;
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(star), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  expectSameTopology(*parsed, star);
  star.baseline_ships_raw = false;
  EXPECT_EQ(toYaml(star).find("baseline_ships"), std::string::npos) << "the default is not written";
  const std::string text = toYaml(makeStarTopology(2, "scans", 51000));
  const auto wrong = parseTopology("baseline_ships: everything\n" + text, "");
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().message.find("baseline_ships: must be processed or raw, got 'everything'"), std::string::npos)
      << wrong.error().message;
  const auto processed = parseTopology("baseline_ships: processed\n" + text, "");
  ASSERT_TRUE(processed.ok()) << processed.error().message;
  EXPECT_FALSE(processed->baseline_ships_raw);
}

TEST(Topology, TreeRoundTripsThroughYaml) {
  TopologyConfig tree = makeTreeTopology(7, "scans", 52000);
  customize(tree);
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(tree), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  expectSameTopology(*parsed, tree);
  EXPECT_EQ(parsed->nodes.size(), 13U);  // 7 edges under 6 binary aggregators
  EXPECT_EQ(parsed->aggregatorLevels("sink"), 3);
  EXPECT_EQ(parsed->sensorsBelow("sink"), (std::vector<std::uint32_t>{1, 2, 3, 4, 5, 6, 7}));
}

// A tree with fanout F: as few levels as F allows, no aggregator over more than F children, and
// subtrees that differ by at most one edge. Checked against the shape by brute force over sizes.
TEST(Topology, TreeWithFanoutHasTheFewestLevelsAndBalancedChildren) {
  const TopologyConfig tree7 = makeTreeTopology(7, "scans", 52000, 4);
  EXPECT_EQ(tree7.children("sink").size(), 2U);
  EXPECT_EQ(tree7.sensorsBelow("agg-1").size(), 4U);
  EXPECT_EQ(tree7.sensorsBelow("agg-2").size(), 3U);
  for (int fanout = 2; fanout <= 5; ++fanout) {
    for (int edges = 2; edges <= 32; ++edges) {  // 10 degrees of overlap fit up to 35 views
      const TopologyConfig t = makeTreeTopology(edges, "scans", 52000, fanout);
      SCOPED_TRACE(std::to_string(edges) + " edges, fanout " + std::to_string(fanout));
      const Expected<TopologyConfig> parsed = parseTopology(toYaml(t), "");
      ASSERT_TRUE(parsed.ok()) << (parsed.ok() ? "" : parsed.error().message);
      EXPECT_EQ(parsed->sensorsBelow("sink").size(), static_cast<std::size_t>(edges));
      int levels = 1;  // the fewest levels that hold the edges
      for (int capacity = fanout; capacity < edges; capacity *= fanout) ++levels;
      EXPECT_EQ(parsed->aggregatorLevels("sink"), levels);
      for (const NodeConfig& n : parsed->nodes) {
        if (n.role != Role::kAggregator) continue;
        const auto children = parsed->children(n.name);
        EXPECT_LE(children.size(), static_cast<std::size_t>(fanout)) << n.name;
        EXPECT_GE(children.size(), 2U) << n.name;
        std::size_t smallest = SIZE_MAX, largest = 0;
        for (const NodeConfig* c : children) {
          const std::size_t below = parsed->sensorsBelow(c->name).size();
          smallest = std::min(smallest, below);
          largest = std::max(largest, below);
        }
        EXPECT_LE(largest - smallest, 1U) << n.name;
      }
    }
  }
  // Fanout 2 is the binary tree the bundled topologies were made with.
  EXPECT_EQ(toYaml(makeTreeTopology(7, "scans", 52000, 2)), toYaml(makeTreeTopology(7, "scans", 52000)));
}

TEST(Topology, RelativeSensorSourceResolvesAgainstBaseDir) {
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(makeStarTopology(2, "scans", 53000)), "base");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->find("edge-1")->sensor->source, fs::path("base") / "scans");
}

TEST(Topology, BundledTopologiesLoadAndMatchTheirGenerators) {
  int files = 0;
  for (const auto& entry : fs::directory_iterator(kSourceDir / "topologies")) {
    if (entry.path().extension() != ".yaml") continue;
    ++files;
    SCOPED_TRACE(entry.path().filename().string());
    const Expected<TopologyConfig> loaded = loadTopology(entry.path());
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    EXPECT_EQ(loaded->name, entry.path().stem().string());
    const auto edges = static_cast<int>(loaded->sensorsBelow(loaded->root()->name).size());
    const fs::path source = loaded->nodes.back().sensor->source;
    EXPECT_TRUE(fs::is_directory(source)) << source;
    const bool star = loaded->name.starts_with("star-");
    const TopologyConfig expected = star ? makeStarTopology(edges, source, loaded->root()->port)
                                         : makeTreeTopology(edges, source, loaded->root()->port);
    expectSameTopology(*loaded, expected);
  }
  EXPECT_GE(files, 6);
}

TEST(Topology, MissingFileIsNotFound) {
  const Expected<TopologyConfig> loaded = loadTopology(kSourceDir / "topologies" / "no-such-topology.yaml");
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.error().code, ErrorCode::kNotFound);
}

// A small valid topology; `globals` and `madc` lines are spliced in, `nodes` replaces the node list.
const std::string kNodes =
    "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
    "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans}}\n";

std::string topologyYaml(const std::string& globals, const std::string& madc = "", const std::string& nodes = kNodes) {
  return "name: t\n" + globals + "madc:\n  eps_m: 0.35\n" + madc + "nodes:\n" + nodes;
}

void expectRejected(const std::string& yaml, const std::string& field) {
  const Expected<TopologyConfig> parsed = parseTopology(yaml, "");
  ASSERT_FALSE(parsed.ok()) << "accepted:\n" << yaml;
  EXPECT_EQ(parsed.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(parsed.error().message.find(field), std::string::npos)
      << "'" << parsed.error().message << "' does not name " << field << "\n" << yaml;
}

// Rejected, with a message containing every phrase (the key, the bound, the reason).
void expectRejectedWith(const std::string& yaml, std::initializer_list<std::string> phrases) {
  const Expected<TopologyConfig> parsed = parseTopology(yaml, "");
  ASSERT_FALSE(parsed.ok()) << "accepted:\n" << yaml;
  EXPECT_EQ(parsed.error().code, ErrorCode::kInvalidArgument);
  for (const std::string& phrase : phrases) {
    EXPECT_NE(parsed.error().message.find(phrase), std::string::npos)
        << "'" << parsed.error().message << "' does not contain '" << phrase << "'\n" << yaml;
  }
}

TEST(Topology, ValidSmallTopologyAndBoundsAreAccepted) {
  for (const std::string& globals : {std::string(), std::string("period_ms: 0.5\n"),
                                     std::string("max_message_bytes: 1048576\n"),
                                     std::string("max_message_bytes: 1073741824\n")}) {
    const Expected<TopologyConfig> parsed = parseTopology(topologyYaml(globals), "");
    EXPECT_TRUE(parsed.ok()) << globals << (parsed.ok() ? "" : parsed.error().message);
  }
  const Expected<TopologyConfig> defaults = parseTopology(topologyYaml(""), "");
  ASSERT_TRUE(defaults.ok()) << defaults.error().message;
  EXPECT_EQ(defaults->madc.clustering.threads, 1U);
  for (int threads : {1, 256}) {
    const Expected<TopologyConfig> parsed = parseTopology(topologyYaml("", "  threads: " + std::to_string(threads) + "\n"), "");
    ASSERT_TRUE(parsed.ok()) << threads << ": " << parsed.error().message;
    EXPECT_EQ(parsed->madc.clustering.threads, static_cast<std::size_t>(threads));
  }
}

TEST(Topology, ObjectsAskForBoxesAndAClassifierWhoseFileResolvesAgainstTheTopology) {
  const std::string nodes = kNodes;
  auto parsed = parseTopology("name: t\nnodes:\n" + nodes, "site");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_FALSE(parsed->objects.boxes);  // off by default: ellipsoids only
  parsed = parseTopology("name: t\nobjects: {boxes: true}\nnodes:\n" + nodes, "site");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_TRUE(parsed->objects.boxes);
  EXPECT_FALSE(parsed->objects.classifier.has_value());
  // A classifier implies boxes.
  parsed = parseTopology("name: t\nobjects: {classifier: models/forest.yml.gz}\nnodes:\n" + nodes, "site");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_TRUE(parsed->objects.boxes);
  EXPECT_EQ(parsed->objects.classifier, std::filesystem::path("site/models/forest.yml.gz"));
  expectRejectedWith("name: t\nobjects: {boxes: false, classifier: m.yml}\nnodes:\n" + nodes, {"objects.boxes", "classifier"});
  expectRejected("name: t\nobjects: {classifier: ''}\nnodes:\n" + nodes, "objects.classifier");
  expectRejected("name: t\nobjects: {boxes: maybe}\nnodes:\n" + nodes, "objects.boxes");
  expectRejected("name: t\nobjects: {box: true}\nnodes:\n" + nodes, "box");
}

TEST(Topology, OutOfRangeValuesNameTheirField) {
  for (const char* v : {"0", "-5"}) expectRejected(topologyYaml(std::string("period_ms: ") + v + "\n"), "period_ms");
  for (const char* v : {"1048575", "1073741825", "-1"}) {
    expectRejected(topologyYaml(std::string("max_message_bytes: ") + v + "\n"), "max_message_bytes");
  }
  for (const char* v : {"0", "-0.1"}) {
    expectRejected("name: t\nmadc: {eps_m: " + std::string(v) + "}\nnodes:\n" + kNodes, "madc.eps_m");
  }
  expectRejected(topologyYaml("", "  min_points: 0\n"), "madc.min_points");
  // Fragments: at least 1 point and at most min_points (the default 10 here).
  for (const char* v : {"0", "11", "-1"}) {
    expectRejected(topologyYaml("", std::string("  fragment_min_points: ") + v + "\n"), "madc.fragment_min_points");
  }
  for (const char* v : {"0", "10", "-1"}) expectRejected(topologyYaml("", std::string("  alpha: ") + v + "\n"), "madc.alpha");
  // alpha_max: 0 (off) or from alpha (1.5 by default) to 10.
  for (const char* v : {"1.4", "10", "-1", "0.5"}) {
    expectRejected(topologyYaml("", std::string("  alpha_max: ") + v + "\n"), "madc.alpha_max");
  }
  for (const char* v : {"0", "257", "1000", "-1"}) {
    expectRejected(topologyYaml("", std::string("  threads: ") + v + "\n"), "madc.threads");
  }
}

TEST(Topology, NonNumbersNameTheirField) {
  expectRejected(topologyYaml("period_ms: fast\n"), "period_ms");
  expectRejected(topologyYaml("max_message_bytes: [1, 2]\n"), "max_message_bytes");
  expectRejected("name: t\nmadc: {eps_m: wide}\nnodes:\n" + kNodes, "madc.eps_m");
  expectRejected(topologyYaml("", "  min_points: 2.5\n"), "madc.min_points");
  expectRejected(topologyYaml("", "  threads: four\n"), "madc.threads");
}

TEST(Topology, BadParentsAndDuplicateNamesAreRejected) {
  const std::string sink = "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n";
  expectRejected(topologyYaml("", "", kNodes + "  - {name: edge-2, id: 2, role: edge, parent: ghost, metrics_port: 50102, "
                                              "sensor: {source: scans}}\n"),
                 "ghost");
  expectRejected(topologyYaml("", "", sink +
                                          "  - {name: agg-a, id: 101, role: aggregator, parent: agg-b, port: 50001, metrics_port: 50201}\n"
                                          "  - {name: agg-b, id: 102, role: aggregator, parent: agg-a, port: 50002, metrics_port: 50202}\n"),
                 "cycle");
  expectRejected(topologyYaml("", "", sink +
                                          "  - {name: agg-a, id: 101, role: aggregator, parent: agg-a, port: 50001, metrics_port: 50201}\n"),
                 "node 'agg-a' is its own parent");
  expectRejected(topologyYaml("", "", kNodes + "  - {name: edge-1, id: 2, role: edge, parent: sink, metrics_port: 50102, "
                                              "sensor: {source: scans}}\n"),
                 "duplicate node name");
}

// Found by fuzzing: a node name with bytes that are not UTF-8 came back from toYaml as another
// name. Names also become file names, pid-file words and metric labels.
TEST(Topology, NamesAreLettersDigitsDotsUnderscoresAndDashes) {
  const auto withEdge = [](const std::string& name) {
    return topologyYaml("", "", kNodes + "  - name: " + name + "\n    id: 2\n    role: edge\n    parent: sink\n"
                                         "    metrics_port: 50102\n    sensor: {source: scans}\n");
  };
  for (const std::string& name : {std::string("e\xff\xff\tdge-7"), std::string("'edge 2'"), std::string("../escape"),
                                 std::string(".hidden"), std::string(65, 'a')}) {
    SCOPED_TRACE(name);
    expectRejectedWith(withEdge(name), {"nodes[2].name", "is not a name", "letters, digits"});
  }
  expectRejectedWith("name: ../t\nnodes:\n" + kNodes, {"topology: name:", "is not a name"});
  for (const std::string& name : {std::string("Edge_2.b-3"), std::string(64, 'z')}) {
    const Expected<TopologyConfig> parsed = parseTopology(withEdge(name), "");
    ASSERT_TRUE(parsed.ok()) << name << ": " << parsed.error().message;
    EXPECT_EQ(parsed->nodes.back().name, name);
  }
}

TEST(Topology, MalformedYamlIsRejected) {
  expectRejected("name: t\nnodes: [unclosed\n", "not valid YAML");
  expectRejected("name: t\n  period_ms: : 3\n\t- x\n", "not valid YAML");
  expectRejected("- just\n- a list\n", "mapping");
}

TEST(Topology, SectionsThatAreNotMappingsAreRejectedNotThrown) {
  expectRejected("name: t\nmadc: 5\nnodes:\n" + kNodes, "madc");
  expectRejected("name: t\nmadc: [1, 2]\nnodes:\n" + kNodes, "madc");
  expectRejected("name: t\npreprocess: 5\nnodes:\n" + kNodes, "preprocess");
  expectRejected("name: t\npreprocess: {crop: 5}\nnodes:\n" + kNodes, "preprocess.crop");
  expectRejected("name: t\npreprocess: {ground: 5}\nnodes:\n" + kNodes, "preprocess.ground");
  const std::string sink = "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n";
  expectRejected(topologyYaml("", "", sink + "  - {name: e, id: 1, role: edge, parent: sink, sensor: scans}\n"), "sensor");
  expectRejected(topologyYaml("", "", sink + "  - {name: e, id: 1, role: edge, parent: sink, sensor: {source: s, split: 3}}\n"),
                 "sensor.split");
  expectRejected(topologyYaml("", "", sink + "  - {name: e, id: 1, role: edge, parent: sink, sensor: {source: s, pose: 3}}\n"),
                 "sensor.pose");
}

TEST(Topology, LimitsAndRolesAreChecked) {
  expectRejected(topologyYaml("period_ms: .inf\n"), "period_ms");
  expectRejected(topologyYaml("period_ms: 60001\n"), "period_ms");
  expectRejected(topologyYaml("", "  min_points: 3000000000\n"), "madc.min_points");
  expectRejected(topologyYaml("", "",
                              "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200, sensor: {source: s}}\n"
                              "  - {name: e, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: s}}\n"),
                 "only edges have a sensor");
}

TEST(Topology, MisspeltKeysAreRejected) {
  expectRejected(topologyYaml("", "  thread: 4\n"), "madc.thread");
  expectRejected(topologyYaml("periodms: 100\n"), "periodms");
  expectRejected("name: t\npreprocess: {ground: {max_tilt: 5}}\nnodes:\n" + kNodes, "preprocess.ground.max_tilt");
  const std::string sink = "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n";
  expectRejected(topologyYaml("", "", sink + "  - {name: e, id: 1, role: edge, parent: sink, prot: 5, sensor: {source: s}}\n"),
                 "prot");
  expectRejected(topologyYaml("", "", sink + "  - {name: e, id: 1, role: edge, parent: sink, sensor: {source: s, rate: 5}}\n"),
                 "sensor.rate");
}

TEST(Topology, ScanSizeBoundAndAdmissionLimitsAreRead) {
  const Expected<TopologyConfig> defaults = parseTopology(topologyYaml(""), "");
  ASSERT_TRUE(defaults.ok()) << defaults.error().message;
  EXPECT_EQ(defaults->max_scan_bytes, kDefaultMaxScanBytes);
  EXPECT_EQ(defaults->admission, AdmissionLimits{});

  const Expected<TopologyConfig> parsed = parseTopology(topologyYaml("max_scan_bytes: 1048576\n"
                                                                     "admission:\n"
                                                                     "  window_periods: 5\n"
                                                                     "  world_extent_m: 500\n"
                                                                     "  max_ellipsoids_per_map: 100\n"
                                                                     "  max_map_bytes: 65536\n"
                                                                     "  min_eigenvalue_m2: 1e-6\n"
                                                                     "  max_eigenvalue_m2: 1e4\n"
                                                                     "  max_condition: 1e9\n"),
                                                        "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->max_scan_bytes, 1048576U);
  const AdmissionLimits expected{5.0, 500.0, 100, 65536, 1e-6, 1e4, 1e9};
  EXPECT_EQ(parsed->admission, expected);

  // Keys left out keep their defaults.
  const Expected<TopologyConfig> partial = parseTopology(topologyYaml("admission: {world_extent_m: 250}\n"), "");
  ASSERT_TRUE(partial.ok()) << partial.error().message;
  AdmissionLimits only_extent;
  only_extent.world_extent_m = 250.0;
  EXPECT_EQ(partial->admission, only_extent);
}

TEST(Topology, BadScanSizeBoundIsRefusedNamingTheKey) {
  for (const char* v : {"0", "-1"}) {
    expectRejectedWith(topologyYaml(std::string("max_scan_bytes: ") + v + "\n"), {"max_scan_bytes", "positive"});
  }
  for (const char* v : {"1.5", "big", "[1, 2]"}) {
    expectRejectedWith(topologyYaml(std::string("max_scan_bytes: ") + v + "\n"), {"max_scan_bytes", "cannot read"});
  }
}

TEST(Topology, BadAdmissionLimitsAreRefusedNamingTheKey) {
  // Value rules come from validateAdmissionLimits; the parser names the key.
  for (const char* key : {"window_periods", "world_extent_m", "min_eigenvalue_m2", "max_eigenvalue_m2", "max_condition"}) {
    for (const char* v : {"0", "-2", ".nan", ".inf"}) {
      SCOPED_TRACE(std::string(key) + ": " + v);
      expectRejectedWith(topologyYaml("admission: {" + std::string(key) + ": " + v + "}\n"), {"admission", key, "positive"});
    }
  }
  for (const char* key : {"max_ellipsoids_per_map", "max_map_bytes"}) {
    SCOPED_TRACE(key);
    expectRejectedWith(topologyYaml("admission: {" + std::string(key) + ": 0}\n"), {"admission", key, "at least 1"});
    expectRejectedWith(topologyYaml("admission: {" + std::string(key) + ": -5}\n"), {"admission." + std::string(key)});
    expectRejectedWith(topologyYaml("admission: {" + std::string(key) + ": 2.5}\n"), {"admission." + std::string(key)});
  }
  expectRejectedWith(topologyYaml("admission: {min_eigenvalue_m2: 10, max_eigenvalue_m2: 1}\n"),
                     {"min_eigenvalue_m2", "max_eigenvalue_m2", "below"});
  expectRejectedWith(topologyYaml("admission: {world_extent_m: far}\n"), {"admission.world_extent_m", "cannot read"});
  expectRejectedWith(topologyYaml("admission: {window_period: 3}\n"), {"admission.window_period", "unknown key"});
  expectRejectedWith(topologyYaml("admission: 5\n"), {"admission", "must be a mapping"});
}

TEST(Topology, AdmissionErrorsFromAFileNameTheFile) {
  const fs::path dir = fs::temp_directory_path() / ("fogmap_topology_" + std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  const fs::path path = dir / "bad-admission.yaml";
  std::ofstream(path) << topologyYaml("admission: {max_condition: -1}\n");
  const Expected<TopologyConfig> loaded = loadTopology(path);
  fs::remove_all(dir);
  ASSERT_FALSE(loaded.ok());
  EXPECT_NE(loaded.error().message.find(path.string()), std::string::npos) << loaded.error().message;
  EXPECT_NE(loaded.error().message.find("max_condition"), std::string::npos) << loaded.error().message;
  EXPECT_NE(loaded.error().message.find("positive"), std::string::npos) << loaded.error().message;
}

TEST(Topology, EpsOutsideTheClusteringRangeIsRefused) {
  // The range is validateClusteringParams's: [kMinEpsM, kMaxEpsM], bounds included.
  for (const char* v : {"1e-300", "0.0009", "100.5", "1e6", ".nan", ".inf", "0", "-0.1"}) {
    SCOPED_TRACE(v);
    expectRejectedWith("name: t\nmadc: {eps_m: " + std::string(v) + "}\nnodes:\n" + kNodes, {"madc.eps_m", "0.001", "100"});
  }
  for (const double eps : {kMinEpsM, kMaxEpsM}) {
    std::ostringstream yaml;
    yaml.precision(17);
    yaml << "name: t\nmadc: {eps_m: " << eps << "}\nnodes:\n" << kNodes;
    const Expected<TopologyConfig> parsed = parseTopology(yaml.str(), "");
    ASSERT_TRUE(parsed.ok()) << eps << ": " << parsed.error().message;
    EXPECT_EQ(parsed->madc.clustering.eps_m, eps);
  }
}

TEST(Topology, ANodeThatIsItsOwnParentIsNamed) {
  // The only parentless candidate points at itself: not "found 0 roots" but the actual mistake.
  expectRejectedWith(topologyYaml("", "",
                                  "  - {name: sink, id: 100, role: aggregator, parent: sink, port: 50000, metrics_port: 50200}\n"
                                  "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: s}}\n"),
                     {"node 'sink' is its own parent"});
  expectRejectedWith(topologyYaml("", "", kNodes + "  - {name: e2, id: 2, role: edge, parent: e2, metrics_port: 50102, "
                                                   "sensor: {source: s}}\n"),
                     {"node 'e2' is its own parent"});
}

TEST(Topology, ACycleWithoutARootIsNamedAsACycle) {
  expectRejectedWith(
      topologyYaml("", "",
                   "  - {name: edge-1, id: 1, role: edge, parent: agg-a, metrics_port: 50101, sensor: {source: s}}\n"
                   "  - {name: agg-a, id: 101, role: aggregator, parent: agg-b, port: 50001, metrics_port: 50201}\n"
                   "  - {name: agg-b, id: 102, role: aggregator, parent: agg-a, port: 50002, metrics_port: 50202}\n"),
      {"cycle", "agg-a -> agg-b -> agg-a"});
}

TEST(Topology, HostMustBeANumericIPv4Address) {
  // The services bind and connect to host:port and fogctl polls /metrics over IPv4, so a name
  // like localhost (or an IPv6 address, which would need brackets) would pass here and then time
  // out at start-up.
  for (const char* host : {"localhost", "sink.local", "::1", "10.0.0.256", "127.1", "\"\"", "\"127.0.0.1 \""}) {
    SCOPED_TRACE(host);
    expectRejectedWith(topologyYaml("", "", "  - {name: sink, id: 100, role: aggregator, host: " + std::string(host) +
                                                ", port: 50000, metrics_port: 50200}\n"
                                                "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, "
                                                "sensor: {source: s}}\n"),
                       {"nodes[0]", "host", "IPv4 address", "127.0.0.1"});
  }
  for (const char* host : {"127.0.0.1", "10.0.0.7", "0.0.0.0"}) {
    const Expected<TopologyConfig> parsed =
        parseTopology(topologyYaml("", "", "  - {name: sink, id: 100, role: aggregator, host: " + std::string(host) +
                                               ", port: 50000, metrics_port: 50200}\n"
                                               "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, "
                                               "sensor: {source: s}}\n"),
                      "");
    ASSERT_TRUE(parsed.ok()) << host << ": " << parsed.error().message;
    EXPECT_EQ(parsed->root()->host, host);
  }
}

// ---------------------------------------------------------------------------------------------
// tls

TEST(Topology, TlsIsOffUnlessTheTopologySaysSo) {
  const Expected<TopologyConfig> parsed = parseTopology(topologyYaml(""), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_FALSE(parsed->tls.has_value());
  EXPECT_FALSE(parsed->tlsIdentity("sink").has_value());
  EXPECT_EQ(toYaml(*parsed).find("tls"), std::string::npos) << "a plaintext topology writes no tls section";
}

TEST(Topology, TlsPathsResolveAgainstTheTopologyDirectoryAndDefaultToCertDir) {
  const std::string nodes =
      "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
      "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans},\n"
      "     tls: {cert: own/e1.pem, key: /etc/fogmap/e1.key}}\n";
  const Expected<TopologyConfig> parsed =
      parseTopology(topologyYaml("tls: {ca: certs/ca.crt, geofence_clients: [operator, ops-2]}\n", "", nodes), "base");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  ASSERT_TRUE(parsed->tls.has_value());
  EXPECT_EQ(parsed->tls->ca, fs::path("base/certs/ca.crt"));
  EXPECT_EQ(parsed->tls->cert_dir, fs::path("base/certs")) << "cert_dir defaults to the CA's directory";
  EXPECT_EQ(parsed->tls->geofence_clients, (std::vector<std::string>{"operator", "ops-2"}));
  const auto sink = parsed->tlsIdentity("sink");
  ASSERT_TRUE(sink.has_value());
  EXPECT_EQ(sink->ca, fs::path("base/certs/ca.crt"));
  EXPECT_EQ(sink->cert, fs::path("base/certs/sink.crt"));
  EXPECT_EQ(sink->key, fs::path("base/certs/sink.key"));
  const auto edge = parsed->tlsIdentity("edge-1");
  ASSERT_TRUE(edge.has_value());
  EXPECT_EQ(edge->cert, fs::path("base/own/e1.pem"));
  EXPECT_EQ(edge->key, fs::path("/etc/fogmap/e1.key"));
  const auto client = parsed->tlsIdentity("operator");  // a client: not a node, same directory
  ASSERT_TRUE(client.has_value());
  EXPECT_EQ(client->cert, fs::path("base/certs/operator.crt"));

  const Expected<TopologyConfig> explicit_dir =
      parseTopology(topologyYaml("tls: {ca: /pki/ca.pem, cert_dir: keys}\n"), "base");
  ASSERT_TRUE(explicit_dir.ok()) << explicit_dir.error().message;
  EXPECT_EQ(explicit_dir->tls->cert_dir, fs::path("base/keys"));
  EXPECT_TRUE(explicit_dir->tls->geofence_clients.empty());
  EXPECT_EQ(explicit_dir->tlsIdentity("sink")->key, fs::path("base/keys/sink.key"));
}

TEST(Topology, TlsRoundTripsThroughYaml) {
  for (const fs::path& ca : {fs::path("certs/ca.crt"), fs::path("ca.crt")}) {
    SCOPED_TRACE(ca.string());
    TopologyConfig tree = makeTreeTopology(3, "scans", 52000);
    customize(tree);
    tree.tls = TlsConfig{ca, ca.parent_path(), {"operator", "ci"}};
    tree.nodes.back().tls = TlsFiles{"own/edge.crt", "own/edge.key"};
    const Expected<TopologyConfig> parsed = parseTopology(toYaml(tree), "");
    ASSERT_TRUE(parsed.ok()) << parsed.error().message << "\n" << toYaml(tree);
    expectSameTopology(*parsed, tree);
    tree.tls->cert_dir = "elsewhere";
    tree.tls->geofence_clients.clear();
    const Expected<TopologyConfig> moved = parseTopology(toYaml(tree), "");
    ASSERT_TRUE(moved.ok()) << moved.error().message;
    expectSameTopology(*moved, tree);
  }
}

TEST(Topology, TlsErrorsNameTheirField) {
  expectRejectedWith(topologyYaml("tls: {cert_dir: certs}\n"), {"tls.ca", "required"});
  expectRejectedWith(topologyYaml("tls: {ca: \"\"}\n"), {"tls.ca", "required"});
  expectRejectedWith(topologyYaml("tls: {ca: [a, b]}\n"), {"tls.ca"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt, cert_dir: \"\"}\n"), {"tls.cert_dir", "required"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt, certdir: x}\n"), {"tls.certdir", "unknown key"});
  expectRejectedWith(topologyYaml("tls: certs/ca.crt\n"), {"tls", "mapping"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt, geofence_clients: operator}\n"), {"tls.geofence_clients", "list"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt, geofence_clients: [ops, \"\"]}\n"), {"tls.geofence_clients[1]"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt, geofence_clients: [\"../x\"]}\n"), {"tls.geofence_clients[0]", "../x"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt, geofence_clients: [ops, ops]}\n"), {"tls.geofence_clients[1]", "twice"});
  const std::string sink = "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n";
  const std::string edge = "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: s}";
  expectRejectedWith(topologyYaml("tls: {ca: c.crt}\n", "", sink + edge + ", tls: {cert: e.crt}}\n"),
                     {"nodes[1].tls.key", "required"});
  expectRejectedWith(topologyYaml("tls: {ca: c.crt}\n", "", sink + edge + ", tls: {cert: e.crt, key: e.key, ca: x}}\n"),
                     {"nodes[1].tls.ca", "unknown key"});
  expectRejectedWith(topologyYaml("", "", sink + edge + ", tls: {cert: e.crt, key: e.key}}\n"),
                     {"nodes[1] (edge-1).tls", "no tls section"});
  // With TLS a node's name is a file name, unless the node names its files itself.
  const std::string ca_edge = "  - {name: ca, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: s}";
  expectRejectedWith(topologyYaml("tls: {ca: c.crt}\n", "", sink + ca_edge + "}\n"), {"nodes[1] (ca).name", "file name"});
  EXPECT_TRUE(parseTopology(topologyYaml("", "", sink + ca_edge + "}\n"), "").ok()) << "without tls any name goes";
  EXPECT_TRUE(parseTopology(topologyYaml("tls: {ca: c.crt}\n", "", sink + ca_edge + ", tls: {cert: e.crt, key: e.key}}\n"), "").ok());
}

// A simulated LiDAR: `source: sim` is the switch, the scene resolves like a source, the LiDAR is a
// name in the scene.
std::string simEdge(const std::string& sensor) {
  return "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
         "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans}}\n"
         "  - {name: edge-2, id: 2, role: edge, parent: sink, metrics_port: 50102, sensor: " + sensor + "}\n";
}

TEST(Topology, SimulatedSensorRoundTripsThroughYaml) {
  TopologyConfig star = makeStarTopology(3, "scans", 54000);
  customize(star);
  SensorConfig& sim = *star.nodes.back().sensor;
  sim.source = kSimSource;
  sim.split.reset();
  sim.scene = "scenes/yard.yaml";
  sim.lidar = "lidar 3: north-east";  // any name the scene gives its LiDAR, quoted by toYaml as needed
  const std::string yaml = toYaml(star);
  const Expected<TopologyConfig> parsed = parseTopology(yaml, "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message << "\n" << yaml;
  expectSameTopology(*parsed, star);
  const SensorConfig& back = *parsed->nodes.back().sensor;
  EXPECT_TRUE(back.simulated());
  EXPECT_EQ(back.source, fs::path("sim")) << "sim is not a path: it does not resolve against the base directory";
  EXPECT_FALSE(parsed->nodes[1].sensor->simulated());
  EXPECT_TRUE(parsed->nodes[1].sensor->scene.empty());
  EXPECT_TRUE(parsed->nodes[1].sensor->lidar.empty());

  const Expected<TopologyConfig> based = parseTopology(yaml, "topologies");
  ASSERT_TRUE(based.ok()) << based.error().message;
  EXPECT_EQ(based->nodes.back().sensor->scene, fs::path("topologies") / "scenes" / "yard.yaml");
  EXPECT_EQ(based->nodes.back().sensor->source, fs::path("sim"));
  const Expected<TopologyConfig> absolute =
      parseTopology(topologyYaml("", "", simEdge("{source: sim, scene: /data/s.yaml, lidar: l1}")), "topologies");
  ASSERT_TRUE(absolute.ok()) << absolute.error().message;
  EXPECT_EQ(absolute->nodes.back().sensor->scene, fs::path("/data/s.yaml"));
  EXPECT_EQ(absolute->nodes.back().sensor->lidar, "l1");
  EXPECT_DOUBLE_EQ(absolute->nodes.back().sensor->rate_hz, 10.0);
}

TEST(Topology, SimulatedSensorNeedsASceneAndALidarAndIsNotSplit) {
  expectRejectedWith(topologyYaml("", "", simEdge("{source: sim, scene: s.yaml}")),
                     {"topology: nodes[2].sensor.lidar: ", "required with source sim"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: sim, scene: s.yaml, lidar: \"\"}")),
                     {"topology: nodes[2].sensor.lidar: ", "required with source sim"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: sim, lidar: l1}")),
                     {"topology: nodes[2].sensor.scene: ", "required with source sim"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, lidar: l1}")),
                     {"topology: nodes[2].sensor.lidar: ", "source sim only", "'scans'"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, scene: s.yaml}")),
                     {"topology: nodes[2].sensor.scene: ", "source sim only"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: sim, scene: s.yaml, lidar: l1, split: {views: 2, index: 0}}")),
                     {"topology: nodes[2].sensor.split: ", "not split"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: sim, scene: s.yaml, lidar: [a, b]}")),
                     {"topology: nodes[2].sensor.lidar"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: sim, scene: s.yaml, lidar: l1, lidars: l2}")),
                     {"nodes[2].sensor.lidars", "unknown key"});
  // A directory that happens to be called sim is written as a path.
  const Expected<TopologyConfig> dir = parseTopology(topologyYaml("", "", simEdge("{source: ./sim}")), "base");
  ASSERT_TRUE(dir.ok()) << dir.error().message;
  EXPECT_FALSE(dir->nodes.back().sensor->simulated());
  EXPECT_EQ(dir->nodes.back().sensor->source, fs::path("base") / "./sim");
}

TEST(Topology, SensorAwareClusteringIsChosenPerEdgeWithItsLidarModel) {
  TopologyConfig star = makeStarTopology(3, "scans", 54000);
  customize(star);
  star.nodes[1].sensor->clustering = ClusteringMode::kSensor;
  star.nodes[1].sensor->model = "HDL-64E";
  const std::string yaml = toYaml(star);
  const Expected<TopologyConfig> parsed = parseTopology(yaml, "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message << "\n" << yaml;
  expectSameTopology(*parsed, star);
  EXPECT_EQ(parsed->nodes[1].sensor->clustering, ClusteringMode::kSensor);
  EXPECT_EQ(parsed->nodes[2].sensor->clustering, ClusteringMode::kExact) << "exact unless the edge says otherwise";
  EXPECT_EQ(yaml.find("clustering: exact"), std::string::npos) << "the default is not written";

  const Expected<TopologyConfig> sim =
      parseTopology(topologyYaml("", "", simEdge("{source: sim, scene: s.yaml, lidar: l1, clustering: sensor, model: VLP-16}")), "");
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  EXPECT_EQ(sim->nodes.back().sensor->model, "VLP-16");
}

TEST(Topology, SensorAwareClusteringMistakesAreNamed) {
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, clustering: rings}")),
                     {"topology: nodes[2].sensor.clustering: ", "exact", "sensor", "'rings'"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, clustering: sensor}")),
                     {"topology: nodes[2].sensor.model: ", "required with clustering: sensor", "VLP-16", "HDL-64E"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, clustering: sensor, model: HDL-128}")),
                     {"topology: nodes[2].sensor.model: ", "no LiDAR model 'HDL-128'", "known: "});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, model: VLP-16}")),
                     {"topology: nodes[2].sensor.model: ", "goes with clustering: sensor only"});
  expectRejectedWith(topologyYaml("", "", simEdge("{source: scans, clustering: [sensor]}")),
                     {"topology: nodes[2].sensor.clustering"});
}

// Cameras and a tracker beside the map's tree: detection nodes send to a tracker, which has no
// parent; every section round-trips.
std::string fusionNodes(const std::string& camera_extra = "", const std::string& tracker_extra = "") {
  return "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
         "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans}}\n"
         "  - {name: fusion, id: 300, role: tracker, port: 50300, metrics_port: 50301" + tracker_extra + "}\n"
         "  - name: cam-1\n    id: 201\n    role: detection\n    parent: fusion\n    metrics_port: 50201\n"
         "    camera:\n      source: sim\n      scene: s.yaml\n      camera: cam-a\n" + camera_extra +
         "      calibration: {fx: 400, fy: 410, cx: 320, cy: 240, width: 640, height: 480,\n"
         "                    pose: {translation_m: [1, 2, 3], rpy_deg: [-90, 0, -90]}}\n";
}

TEST(Topology, DetectionAndTrackerNodesRoundTripThroughYaml) {
  const Expected<TopologyConfig> parsed = parseTopology(
      topologyYaml("", "", fusionNodes("      detector: {kind: truth, truth: {miss_rate: 0.3, box_jitter_px: 2, latency_ms: 40}}\n",
                                       ", tracker: {association: paper, rho_overlay_m: 5, confirm_hits: 4, publish_lost_s: 0.2}")),
      "base");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->root()->name, "sink");
  const NodeConfig& tracker = *parsed->find("fusion");
  EXPECT_EQ(tracker.role, Role::kTracker);
  ASSERT_TRUE(tracker.tracker.has_value());
  EXPECT_EQ(tracker.tracker->tracking.association, tracking::Association::kPaper);
  EXPECT_DOUBLE_EQ(tracker.tracker->tracking.rho_overlay_m, 5.0);
  EXPECT_EQ(tracker.tracker->tracking.confirm_hits, 4);
  EXPECT_DOUBLE_EQ(tracker.tracker->tracking.publish_lost_s, 0.2);
  const auto cameras = parsed->camerasOf("fusion");
  ASSERT_EQ(cameras.size(), 1U);
  const CameraNodeConfig& cam = *cameras[0]->camera;
  EXPECT_TRUE(cam.simulated());
  EXPECT_EQ(cam.scene, fs::path("base") / "s.yaml");
  EXPECT_EQ(cam.camera, "cam-a");
  EXPECT_TRUE(cam.truth);
  EXPECT_DOUBLE_EQ(cam.truth_replay.miss_rate, 0.3);
  EXPECT_DOUBLE_EQ(cam.truth_replay.latency_ms, 40.0);
  EXPECT_EQ(cam.calibration.name, "cam-1");
  EXPECT_DOUBLE_EQ(cam.calibration.fy, 410.0);
  // Pose: camera -> common frame; the camera centre is its translation, and the camera's z axis
  // (rpy -90, 0, -90: x right, y down, z forward) looks along the common frame's +x.
  EXPECT_LT((cam.calibration.centre() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-12);
  EXPECT_LT((cam.calibration.toCamera(Eigen::Vector3d(11, 2, 3)) - Eigen::Vector3d(0, 0, 10)).norm(), 1e-9);

  const std::string yaml = toYaml(*parsed);
  const Expected<TopologyConfig> again = parseTopology(yaml, "");
  ASSERT_TRUE(again.ok()) << again.error().message << "\n" << yaml;
  expectSameTopology(*again, *parsed);
  const CameraNodeConfig& back = *again->find("cam-1")->camera;
  EXPECT_TRUE(back.truth);
  EXPECT_DOUBLE_EQ(back.truth_replay.box_jitter_px, 2.0);
  EXPECT_LT((back.calibration.world_to_camera.matrix() - cam.calibration.world_to_camera.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(again->find("fusion")->tracker->tracking.association, tracking::Association::kPaper);

  // A HOG detector's settings and a dnn's paths round-trip too.
  const Expected<TopologyConfig> hog = parseTopology(
      topologyYaml("", "", fusionNodes("      detector: {kind: hog, hog: {upscale: 1.5, hit_threshold: 0.2}}\n")), "");
  ASSERT_TRUE(hog.ok()) << hog.error().message;
  const auto hog_again = parseTopology(toYaml(*hog), "");
  ASSERT_TRUE(hog_again.ok()) << hog_again.error().message;
  EXPECT_DOUBLE_EQ(hog_again->find("cam-1")->camera->detector.hog.upscale, 1.5);
  const Expected<TopologyConfig> dnn = parseTopology(
      topologyYaml("", "", fusionNodes("      detector: {kind: dnn, dnn: {model_path: m.onnx, names_path: n.txt, output: yolo-export}}\n")),
      "models");
  ASSERT_TRUE(dnn.ok()) << dnn.error().message;
  EXPECT_EQ(dnn->find("cam-1")->camera->detector.dnn.model_path, (fs::path("models") / "m.onnx").string());
  EXPECT_EQ(dnn->find("cam-1")->camera->detector.dnn.output, camera::DnnOutput::kYoloExport);
  const auto dnn_again = parseTopology(toYaml(*dnn), "");
  ASSERT_TRUE(dnn_again.ok()) << dnn_again.error().message;
  EXPECT_EQ(dnn_again->find("cam-1")->camera->detector.dnn.names_path, (fs::path("models") / "n.txt").string());
}

TEST(Topology, DetectionAndTrackerMistakesAreNamed) {
  const std::string cal = "calibration: {fx: 400, fy: 400, cx: 320, cy: 240, width: 640, height: 480}";
  const std::string head = "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
                           "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans}}\n";
  expectRejectedWith(topologyYaml("", "", head + "  - {name: c, id: 2, role: detection, parent: sink, metrics_port: 1, camera: {source: imgs, " + cal + "}}\n"),
                     {"nodes[2] (c).parent", "'sink' is not a tracker"});
  expectRejectedWith(topologyYaml("", "", head + "  - {name: t, id: 3, role: tracker, metrics_port: 2}\n"),
                     {"nodes[2] (t)", "a tracker needs a port"});
  expectRejectedWith(topologyYaml("", "", head + "  - {name: t, id: 3, role: tracker, parent: sink, port: 3, metrics_port: 2}\n"),
                     {"nodes[2] (t).parent", "a tracker has no parent"});
  expectRejectedWith(topologyYaml("", "", head + "  - {name: t, id: 3, role: tracker, port: 3, metrics_port: 2}\n"
                                                 "  - {name: c, id: 2, role: detection, parent: t, metrics_port: 1}\n"),
                     {"nodes[3] (c)", "needs a camera"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("      detector: {kind: yolo}\n")),
                     {"nodes[3].camera.detector.kind", "hog, cascade, dnn or truth"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("      detector: {kind: truth, truth: {miss_rate: 1.5}}\n")),
                     {"nodes[3].camera.detector.truth.miss_rate", "[0, 1]"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {association: greedy}")),
                     {"nodes[2].tracker.association", "'greedy'"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {eps_sync_s: 0}")), {"nodes[2].tracker", "eps_sync_s"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {publish_lost_s: 3}")), {"nodes[2].tracker", "publish_lost_s"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {publish_lost_s: -0.1}")), {"nodes[2].tracker", "publish_lost_s"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {eps_sync: 0.1}")), {"nodes[2].tracker.eps_sync", "unknown key"});
  // A camera without a calibration, and truth without a simulated scene.
  expectRejectedWith(topologyYaml("", "", head + "  - {name: t, id: 3, role: tracker, port: 3, metrics_port: 2}\n"
                                                 "  - {name: c, id: 2, role: detection, parent: t, metrics_port: 1, camera: {source: imgs}}\n"),
                     {"nodes[3].camera.calibration", "is required"});
  expectRejectedWith(topologyYaml("", "", head + "  - {name: t, id: 3, role: tracker, port: 3, metrics_port: 2}\n"
                                                 "  - {name: c, id: 2, role: detection, parent: t, metrics_port: 1, camera: {source: imgs, detector: {kind: truth}, " + cal + "}}\n"),
                     {"nodes[3].camera.detector.kind", "needs source sim"});
  expectRejectedWith(topologyYaml("", "", head + "  - {name: t, id: 3, role: tracker, port: 3, metrics_port: 2}\n"
                                                 "  - {name: c, id: 2, role: detection, parent: t, metrics_port: 1, camera: {source: imgs, calibration: {fx: -1}}}\n"),
                     {"nodes[3].camera.calibration", "fx and fy must be positive"});
  expectRejectedWith(topologyYaml("", "", head + "  - {name: e, id: 3, role: edge, parent: sink, metrics_port: 2, sensor: {source: s}, camera: {source: imgs, " + cal + "}}\n"),
                     {"nodes[2] (e).camera", "only detection nodes"});
}

// Two edges streaming displacement centroids to a tracker whose input is centroids, and a
// detection node; `edge2` and `tracker` replace the second edge's displacement and the tracker's
// section.
std::string centroidNodes(const std::string& edge2 = "{tracker: fusion}",
                          const std::string& tracker = "{input: centroids, centroid_merge_m: 0.5}") {
  return "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
         "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans},\n"
         "     displacement: {tracker: fusion, preset: outdoor, min_points: 6, min_z_variance_m2: 0.02}}\n"
         "  - {name: edge-2, id: 2, role: edge, parent: sink, metrics_port: 50102, sensor: {source: scans},\n"
         "     displacement: " + edge2 + "}\n"
         "  - {name: fusion, id: 300, role: tracker, port: 50300, metrics_port: 50301, tracker: " + tracker + "}\n"
         "  - name: cam-1\n    id: 201\n    role: detection\n    parent: fusion\n    metrics_port: 50201\n"
         "    camera: {source: imgs, calibration: {fx: 400, fy: 400, cx: 320, cy: 240, width: 640, height: 480}}\n";
}

TEST(Topology, EdgeDisplacementAndCentroidInputRoundTripThroughYaml) {
  const Expected<TopologyConfig> parsed = parseTopology(topologyYaml("", "", centroidNodes()), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const NodeConfig& tracker = *parsed->find("fusion");
  EXPECT_EQ(tracker.tracker->input, TrackerInput::kCentroids);
  EXPECT_DOUBLE_EQ(tracker.tracker->centroid_merge_m, 0.5);
  const auto edges = parsed->centroidEdgesOf("fusion");
  ASSERT_EQ(edges.size(), 2U);
  EXPECT_EQ(edges[0]->name, "edge-1");
  // The outdoor preset, then the keys given.
  tracking::DisplacementParams outdoor = tracking::DisplacementParams::outdoor();
  outdoor.min_points = 6;
  outdoor.min_z_variance_m2 = 0.02;
  EXPECT_EQ(edges[0]->displacement->params, outdoor);
  EXPECT_DOUBLE_EQ(edges[0]->displacement->params.voxel_m, 1.0);
  // No preset: the indoor one (the paper's Table 1).
  EXPECT_EQ(edges[1]->displacement->params, tracking::DisplacementParams::indoor());
  EXPECT_TRUE(parsed->centroidEdgesOf("sink").empty());
  EXPECT_FALSE(parsed->find("sink")->displacement.has_value());

  const std::string yaml = toYaml(*parsed);
  const Expected<TopologyConfig> again = parseTopology(yaml, "");
  ASSERT_TRUE(again.ok()) << again.error().message << "\n" << yaml;
  expectSameTopology(*again, *parsed);

  // A tracker without input reads the global map, and writes no input back.
  const Expected<TopologyConfig> global = parseTopology(topologyYaml("", "", fusionNodes()), "");
  ASSERT_TRUE(global.ok()) << global.error().message;
  EXPECT_EQ(global->find("fusion")->tracker->input, TrackerInput::kGlobalMap);
  EXPECT_EQ(toYaml(*global).find("input:"), std::string::npos);
}

TEST(Topology, DisplacementAndCentroidInputMistakesAreNamed) {
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: nobody}")),
                     {"nodes[2] (edge-2).displacement.tracker", "no node named 'nobody'"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: sink}")),
                     {"nodes[2] (edge-2).displacement.tracker", "'sink' is not a tracker (role aggregator)"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion}", "{input: global_map}")),
                     {"nodes[1] (edge-1).displacement.tracker", "reads the root's global map", "input: centroids"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {input: centroids}")),
                     {"nodes[2] (fusion).tracker.input", "no edge sends this tracker any"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{preset: indoor}")), {"nodes[2].displacement.tracker", "is required"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, preset: underwater}")),
                     {"nodes[2].displacement.preset", "indoor", "outdoor", "'underwater'"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, voxel_m: 0}")),
                     {"nodes[2].displacement", "voxel_m", "above 0"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, neighbour_m: .nan}")),
                     {"nodes[2].displacement", "neighbour_m"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, min_points: 1}")),
                     {"nodes[2].displacement", "min_points", "at least 2"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, min_neighbours: -3}")),
                     {"nodes[2].displacement.min_neighbours", "-3"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, min_z_variance_m2: -0.1}")),
                     {"nodes[2].displacement", "min_z_variance_m2"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion, voxel: 0.1}")),
                     {"nodes[2].displacement.voxel", "unknown key"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion}", "{input: lidar}")),
                     {"nodes[3].tracker.input", "global_map", "centroids", "'lidar'"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion}", "{input: centroids, centroid_merge_m: -1}")),
                     {"nodes[3].tracker.centroid_merge_m", "[0, 100]"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {centroid_merge_m: 1}")),
                     {"nodes[2].tracker.centroid_merge_m", "input: centroids"});
  expectRejectedWith(topologyYaml("", "", centroidNodes("{tracker: fusion}", "{input: centroids, visible_side_max_radius_m: 11}")),
                     {"nodes[3].tracker.visible_side_max_radius_m", "[0, 10]"});
  expectRejectedWith(topologyYaml("", "", fusionNodes("", ", tracker: {visible_side_max_radius_m: 0.3}")),
                     {"nodes[2].tracker.visible_side_max_radius_m", "input: centroids"});
  expectRejectedWith(topologyYaml("", "", kNodes + "  - {name: t, id: 3, role: tracker, port: 3, metrics_port: 2, "
                                                   "displacement: {tracker: t}, tracker: {input: centroids}}\n"),
                     {"nodes[2] (t).displacement", "only edges"});
}

}  // namespace
}  // namespace fogmap
