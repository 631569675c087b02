// A topology from a scene (common/sim/scene_topology.hpp): one simulated edge per LiDAR at the
// LiDAR's pose, star or tree, that parses back as written.
#include "common/config/displacement_node.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/config/tracker_node.hpp"
#include "common/sim/scene_topology.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "common/sim/generators.hpp"

namespace fogmap::sim {
namespace {

std::vector<const NodeConfig*> edgesOf(const TopologyConfig& t) {
  std::vector<const NodeConfig*> out;
  for (const NodeConfig& n : t.nodes) {
    if (n.role == Role::kEdge) out.push_back(&n);
  }
  return out;
}

TEST(SceneTopology, OneSimulatedEdgePerLidarAtItsPoseInAStarAndATree) {
  const Scene scene = randomScene(20, 3, 5);
  for (const bool tree : {false, true}) {
    SCOPED_TRACE(tree ? "tree" : "star");
    SceneTopologyOptions options;
    options.tree = tree;
    options.base_port = 47000;
    const TopologyConfig t = sceneTopology(scene, "scenes/random.yaml", options);
    // Through the file format, as fogctl writes it and the services read it.
    const Expected<TopologyConfig> parsed = parseTopology(toYaml(t), "run");
    ASSERT_TRUE(parsed.ok()) << parsed.error().message << "\n" << toYaml(t);
    EXPECT_EQ(parsed->name, scene.name + (tree ? "-tree-3" : "-star-3"));
    const auto edges = edgesOf(*parsed);
    ASSERT_EQ(edges.size(), 3U);
    EXPECT_EQ(parsed->nodes.size(), tree ? 5U : 4U) << "a tree of 3 edges has the sink and one aggregator";
    EXPECT_EQ(parsed->sensorsBelow(parsed->root()->name), (std::vector<std::uint32_t>{1, 2, 3}));
    for (std::size_t i = 0; i < 3; ++i) {
      const NodeConfig& edge = *edges[i];
      const LidarConfig& lidar = scene.lidars[i];
      EXPECT_EQ(edge.id, i + 1);
      EXPECT_EQ(edge.name, "edge-" + lidar.name);
      ASSERT_TRUE(edge.sensor.has_value());
      EXPECT_TRUE(edge.sensor->simulated());
      EXPECT_EQ(edge.sensor->lidar, lidar.name);
      EXPECT_EQ(edge.sensor->scene, std::filesystem::path("run") / "scenes" / "random.yaml");
      EXPECT_FALSE(edge.sensor->split.has_value());
      EXPECT_LT((edge.sensor->pose.translation() - lidar.pose.translation()).norm(), 1e-9) << edge.name;
      EXPECT_LT((edge.sensor->pose.linear() - lidar.pose.linear()).cwiseAbs().maxCoeff(), 1e-9) << edge.name;
      // Sparse LiDARs of known models: sensor-aware clustering with the LiDAR's beam table.
      EXPECT_EQ(edge.sensor->clustering, ClusteringMode::kSensor);
      EXPECT_EQ(edge.sensor->model, lidar.model);
    }
    EXPECT_EQ(parsed->madc.fragment_min_points, std::optional<std::size_t>(1)) << "every cluster ships, as a fragment";
    EXPECT_DOUBLE_EQ(parsed->madc.alpha_max, 2.5) << "ellipsoids reach their clusters' ends";
    // The common frame is the scene's: the crop box holds the whole area and its tallest object.
    ASSERT_TRUE(parsed->preprocess.crop.has_value());
    EXPECT_DOUBLE_EQ(parsed->preprocess.crop->max_m.x(), scene.extent_m);
    EXPECT_DOUBLE_EQ(parsed->preprocess.crop->min_m.y(), -scene.extent_m);
    EXPECT_LT(parsed->preprocess.crop->min_m.z(), scene.ground.height_m);
    ASSERT_TRUE(parsed->preprocess.ground.has_value());
    EXPECT_EQ(parsed->preprocess.ground->ground_z_hint_m, scene.ground.height_m);
  }
}

TEST(SceneTopology, ThePapersMadcIsOneOptionAway) {
  const Scene scene = randomScene(20, 3, 5);
  SceneTopologyOptions options;
  options.mapping = paperMapping();
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(sceneTopology(scene, "s.yaml", options)), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_FALSE(parsed->madc.fragment_min_points.has_value());
  EXPECT_DOUBLE_EQ(parsed->madc.alpha_max, 0.0) << "alpha for every ellipsoid";
  for (const NodeConfig* edge : edgesOf(*parsed)) {
    EXPECT_EQ(edge->sensor->clustering, ClusteringMode::kExact);
    EXPECT_TRUE(edge->sensor->model.empty());
  }
}

TEST(SceneTopology, WithCentroidInputEveryEdgeStreamsItsCentroidsToTheTracker) {
  const Scene scene = movingScene(3, 1, 3, 2, 4);
  SceneTopologyOptions options;
  options.tracker = true;
  options.tracker_input = TrackerInput::kCentroids;
  options.displacement = tracking::DisplacementParams::outdoor();
  options.displacement.min_points = 6;
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(sceneTopology(scene, "s.yaml", options)), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const NodeConfig* tracker = parsed->find(kTrackerNodeName);
  ASSERT_NE(tracker, nullptr);
  EXPECT_EQ(tracker->tracker->input, TrackerInput::kCentroids);
  EXPECT_EQ(parsed->camerasOf(tracker->name).size(), 2U);
  const auto edges = parsed->centroidEdgesOf(tracker->name);
  ASSERT_EQ(edges.size(), 3U);
  for (const NodeConfig* e : edges) {
    EXPECT_EQ(e->displacement->tracker, tracker->name);
    EXPECT_EQ(e->displacement->params, options.displacement) << e->name;
  }
  // The default: the tracker reads the root's global maps, and no edge runs the detector.
  options.tracker_input = TrackerInput::kGlobalMap;
  const TopologyConfig global = sceneTopology(scene, "s.yaml", options);
  EXPECT_EQ(global.find(kTrackerNodeName)->tracker->input, TrackerInput::kGlobalMap);
  for (const NodeConfig* e : edgesOf(global)) EXPECT_FALSE(e->displacement.has_value()) << e->name;
}

TEST(SceneTopology, EdgeNamesAreNodeNamesAndStayApart) {
  Scene scene;
  scene.name = "yard 7/north";
  for (const char* name : {"north mast", "north/mast", "north_mast", "a.b-c_D9", "\xc3\xa9t\xc3\xa9"}) {
    LidarConfig l;
    l.name = name;
    scene.lidars.push_back(l);
  }
  LidarConfig long_name;
  long_name.name = std::string(100, 'x');
  scene.lidars.push_back(long_name);
  const TopologyConfig t = sceneTopology(scene, "s.yaml");
  std::vector<std::string> names;
  for (const NodeConfig* edge : edgesOf(t)) names.push_back(edge->name);
  EXPECT_EQ(names, (std::vector<std::string>{"edge-north_mast", "edge-north_mast-2", "edge-north_mast-3", "edge-a.b-c_D9",
                                             "edge-__t__", "edge-" + std::string(59, 'x')}));
  EXPECT_EQ(t.name, "yard_7_north-star-6");
  const Expected<TopologyConfig> parsed = parseTopology(toYaml(t), "");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  // The sensors still name the scene's LiDARs as the scene spells them.
  EXPECT_EQ(parsed->find("edge-north_mast-2")->sensor->lidar, "north/mast");
  EXPECT_EQ(parsed->find("edge-__t__")->sensor->lidar, "\xc3\xa9t\xc3\xa9");
}

TEST(SceneTopology, ATiltedGroundIsNotHintedAndMayTiltFurtherThanTheDefault) {
  Scene scene = randomScene(0, 2, 1);
  scene.ground.tilt_deg = 20.0;
  const TopologyConfig t = sceneTopology(scene, "s.yaml");
  ASSERT_TRUE(t.preprocess.ground.has_value());
  EXPECT_FALSE(t.preprocess.ground->ground_z_hint_m.has_value());
  EXPECT_GE(t.preprocess.ground->max_tilt_deg, 25.0);
  // The crop box reaches the ground at both ends of the slope.
  EXPECT_LT(t.preprocess.crop->min_m.z(), scene.ground.heightAt(-scene.extent_m));
  EXPECT_GT(t.preprocess.crop->max_m.z(), scene.ground.heightAt(scene.extent_m));
}

}  // namespace
}  // namespace fogmap::sim
