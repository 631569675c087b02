#include "services/edge_cluster/edge_node.hpp"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <iostream>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/classify/cluster_views.hpp"
#include "common/config/displacement_node.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/clustering.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/perception/preprocess.hpp"
#include "common/perception/virtual_lidar.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/same_points.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kNode = 7;
constexpr std::uint64_t kFrame = 42;
constexpr std::int64_t kSensorTimeNs = 1'700'000'000'123'456'789;
constexpr std::size_t kFourMiB = 4U << 20;

const Cloud& realScan() {
  static const Cloud scan = [] {
    Expected<LoadedCloud> loaded = readCloud(fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a" / "0000000000.bin");
    EXPECT_TRUE(loaded.ok()) << loaded.error().message;
    return loaded ? loaded->points : Cloud{};
  }();
  return scan;
}

EdgeConfig edgeConfig(Mode mode) {
  EdgeConfig config;
  config.node = kNode;
  config.mode = mode;
  config.preprocess.crop = CropBox{};
  config.preprocess.ground = GroundParams{};
  return config;
}

// The oracle: the library pre-processing and clustering run directly.
Cloud preprocessed(const Cloud& scan, const EdgeConfig& config) {
  Expected<Cloud> cloud = preprocess(scan, config.preprocess);
  EXPECT_TRUE(cloud.ok()) << cloud.error().message;
  return cloud ? *cloud : Cloud{};
}

MapHeader expectedHeader() {
  MapHeader header;
  header.node = kNode;
  header.epoch = kFrame;
  header.sensor_time_ns = kSensorTimeNs;
  header.contributing_nodes = {kNode};
  return header;
}

EdgeOutput process(EdgeNode edge, const Cloud& scan) {
  Expected<EdgeOutput> output = edge.processFrame(scan, kFrame, kSensorTimeNs);
  EXPECT_TRUE(output.ok()) << output.error().message;
  return output ? *output : EdgeOutput{};
}

// Checks the chunks tile the scan in order and returns their points and labels joined.
struct Reassembled {
  Cloud points;
  std::vector<std::int32_t> labels;
};
Reassembled reassemble(const std::vector<PointChunk>& chunks) {
  Reassembled all;
  for (std::size_t c = 0; c < chunks.size(); ++c) {
    const PointChunk& chunk = chunks[c];
    EXPECT_EQ(chunk.header, expectedHeader());
    EXPECT_EQ(chunk.chunk, c);
    EXPECT_EQ(chunk.chunk_count, chunks.size());
    EXPECT_EQ(chunk.first_point, all.points.size());
    all.points.insert(all.points.end(), chunk.points.begin(), chunk.points.end());
    all.labels.insert(all.labels.end(), chunk.labels.begin(), chunk.labels.end());
  }
  for (const PointChunk& chunk : chunks) EXPECT_EQ(chunk.total_points, all.points.size());
  return all;
}

using test_support::samePoints;

Cloud withoutIntensity(Cloud cloud) {
  for (Point& p : cloud) p.intensity = 0.0F;
  return cloud;
}

TEST(EdgeNode, MadcMapHasOneEllipsoidPerClusterOfThePreprocessedScan) {
  const EdgeConfig config = edgeConfig(Mode::kMadc);
  const Cloud points = preprocessed(realScan(), config);
  const Clustering clustering = euclideanClusters(points, config.madc.clustering);
  ASSERT_GT(clustering.cluster_count, 10) << "the real scan has many obstacles";

  const EdgeOutput output = process(EdgeNode(config), realScan());
  ASSERT_TRUE(output.map.has_value());
  EXPECT_TRUE(output.chunks.empty());
  EXPECT_EQ(output.map->header, expectedHeader());
  EXPECT_EQ(output.map->map.ellipsoidCount(), static_cast<std::size_t>(clustering.cluster_count));
  EXPECT_EQ(output.map->map.objects.size(), static_cast<std::size_t>(clustering.cluster_count));
  EXPECT_EQ(output.clusters, static_cast<std::size_t>(clustering.cluster_count));
  EXPECT_EQ(output.points_in, realScan().size());
  EXPECT_EQ(output.points_out, points.size());
  EXPECT_GT(output.clustering_seconds, 0.0);

  std::set<std::uint32_t> indices;
  for (const MapObject& object : output.map->map.objects) {
    for (const Ellipsoid& e : object.ellipsoids) {
      EXPECT_EQ(e.id.node, kNode);
      EXPECT_EQ(e.id.frame, kFrame);
      indices.insert(e.id.index);
    }
  }
  ASSERT_EQ(indices.size(), static_cast<std::size_t>(clustering.cluster_count));
  EXPECT_EQ(*indices.begin(), 0U);
  EXPECT_EQ(*indices.rbegin(), static_cast<std::uint32_t>(clustering.cluster_count - 1));
}

TEST(EdgeNode, WithObjectsEachClusterOfMinPointsCarriesItsBoxAndClassAndFragmentsNeither) {
  EdgeConfig config = edgeConfig(Mode::kMadc);
  config.madc.fragment_min_points = 3;
  config.madc.clustering.min_points = 3;  // what edgeConfigFor sets: the edge keeps its fragments
  config.boxes = true;
  config.box_min_points = 10;
  config.preprocess.sensor_to_common.translation() = Eigen::Vector3d(2.0, -1.0, 1.7);
  TopologyConfig topology;
  topology.objects.boxes = true;
  topology.objects.classifier = fs::path(FOGMAP_SOURCE_DIR) / "data" / "models" / "lidar_classifier.yml.gz";
  auto classifier = loadClassifierOf(topology);
  ASSERT_TRUE(classifier.ok()) << classifier.error().message;
  ASSERT_NE(*classifier, nullptr);
  config.classifier = *classifier;

  const EdgeOutput output = process(EdgeNode(config), realScan());
  ASSERT_TRUE(output.map.has_value());
  // The oracle: the scan's clusters with the vehicles' parts joined, each box containing its
  // cluster and anchored for the sensor.
  const Cloud points = preprocessed(realScan(), config);
  const Eigen::Vector3d sensor = config.preprocess.sensor_to_common.translation();
  Clustering clustering = euclideanClusters(points, config.madc.clustering);
  const auto views = clusterViews(points, clustering, sensor, config.classifier.get(), 10);
  ASSERT_TRUE(views.ok()) << views.error().message;
  const auto joined = joinedVehicleParts(points, clustering, *views, sensor);
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  const auto clusters_before = static_cast<std::size_t>(clustering.cluster_count);
  if (*joined) {
    std::cout << "vehicle parts joined: " << clustering.cluster_count << " clusters became " << (*joined)->clustering.cluster_count << "\n";
    clustering = (*joined)->clustering;
  }
  ASSERT_EQ(output.map->map.objects.size(), static_cast<std::size_t>(clustering.cluster_count));
  EXPECT_EQ(output.vehicle_parts_joined, clusters_before - static_cast<std::size_t>(clustering.cluster_count));
  const std::vector<Cloud> clusters = pointsByCluster(points, clustering);
  std::size_t boxes = 0;
  std::size_t fragments = 0;
  std::set<ObjectClass> classes;
  for (const MapObject& object : output.map->map.objects) {
    const Ellipsoid& e = object.ellipsoids.at(0);
    const Cloud& cluster = clusters.at(e.id.index);
    ASSERT_EQ(e.point_count, cluster.size());
    if (cluster.size() < 10) {
      EXPECT_FALSE(e.box.has_value());
      EXPECT_FALSE(e.label.has_value());
      ++fragments;
      continue;
    }
    ASSERT_TRUE(e.box.has_value());
    ASSERT_TRUE(e.label.has_value());
    ++boxes;
    classes.insert(e.label->object_class);
    EXPECT_GE(e.label->confidence, 0.0);
    EXPECT_LE(e.label->confidence, 1.0);
    const OrientedBox& b = *e.box;
    EXPECT_EQ(b.anchor, b.anchorFor(sensor));
    const Eigen::Vector2d u(std::cos(b.yaw), std::sin(b.yaw));
    const Eigen::Vector2d v(-u.y(), u.x());
    for (const Point& p : cluster) {
      const Eigen::Vector2d d = Eigen::Vector2d(p.x, p.y) - b.centre.head<2>();
      EXPECT_LE(std::abs(d.dot(u)), 0.5 * b.length + 1e-3);
      EXPECT_LE(std::abs(d.dot(v)), 0.5 * b.width + 1e-3);
      EXPECT_LE(std::abs(p.z - b.centre.z()), 0.5 * b.height + 1e-3);
    }
  }
  EXPECT_GT(boxes, 10U);
  EXPECT_GT(fragments, 0U);
  EXPECT_TRUE(classes.count(ObjectClass::kCar)) << "the KITTI street has parked cars";
}

TEST(EdgeNode, AMissingOrCorruptClassifierIsAnErrorNamingTheFile) {
  const test_support::ScratchDir scratch("edge-classifier");
  TopologyConfig topology;
  topology.objects.boxes = true;
  topology.objects.classifier = scratch.path() / "absent.yml.gz";
  auto missing = loadClassifierOf(topology);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("objects.classifier"), std::string::npos) << missing.error().message;
  EXPECT_NE(missing.error().message.find("absent.yml.gz"), std::string::npos) << missing.error().message;
  topology.objects.classifier = scratch.path() / "corrupt.yml";
  std::ofstream(*topology.objects.classifier) << "%YAML:1.0\nnot: a model\n";
  auto corrupt = loadClassifierOf(topology);
  ASSERT_FALSE(corrupt.ok());
  EXPECT_NE(corrupt.error().message.find("corrupt.yml"), std::string::npos) << corrupt.error().message;
  // Without a classifier: nothing to load.
  topology.objects.classifier.reset();
  auto none = loadClassifierOf(topology);
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(*none, nullptr);
}

TEST(EdgeNode, BaselineChunksReassembleToThePreprocessedScan) {
  EdgeConfig config = edgeConfig(Mode::kBaseline);
  config.max_points_per_chunk = 5000;  // several chunks from one real scan
  const Cloud points = preprocessed(realScan(), config);
  ASSERT_GT(points.size(), 3 * config.max_points_per_chunk);

  const EdgeOutput output = process(EdgeNode(config), realScan());
  EXPECT_FALSE(output.map.has_value());
  EXPECT_EQ(output.clusters, 0U);
  EXPECT_EQ(output.chunks.size(), (points.size() + 4999) / 5000);
  const Reassembled all = reassemble(output.chunks);
  EXPECT_TRUE(samePoints(all.points, withoutIntensity(points)));
  EXPECT_TRUE(all.labels.empty());
  for (const PointChunk& chunk : output.chunks) EXPECT_LE(chunk.points.size(), config.max_points_per_chunk);
}

TEST(EdgeNode, ABaselineThatShipsWholeScansOnlyMovesThemIntoTheCommonFrame) {
  EdgeConfig config = edgeConfig(Mode::kBaseline);
  config.ship_raw = true;
  config.preprocess.sensor_to_common = Eigen::Translation3d(1.0, -2.0, 0.5) * Eigen::Isometry3d::Identity();
  const Cloud& scan = realScan();
  ASSERT_TRUE(config.preprocess.ground.has_value()) << "the test config removes the ground, whole scans keep it";
  const EdgeOutput output = process(EdgeNode(config), scan);
  EXPECT_FALSE(output.map.has_value());
  const Reassembled all = reassemble(output.chunks);
  ASSERT_EQ(all.points.size(), scan.size()) << "nothing cropped, downsampled or removed";
  EXPECT_EQ(output.points_out, scan.size());
  for (std::size_t i = 0; i < scan.size(); i += 997) {
    const Eigen::Vector3d expected = config.preprocess.sensor_to_common * Eigen::Vector3d(scan[i].x, scan[i].y, scan[i].z);
    EXPECT_NEAR(all.points[i].x, expected.x(), 1e-5);
    EXPECT_NEAR(all.points[i].y, expected.y(), 1e-5);
    EXPECT_NEAR(all.points[i].z, expected.z(), 1e-5);
  }
  // The same node in the other modes pre-processes as ever.
  config.mode = Mode::kExt;
  EXPECT_LT(process(EdgeNode(config), scan).points_out, scan.size());
}

TEST(EdgeNode, DefaultChunksStayWellUnderTheMessageLimit) {
  // A dense synthetic scan well above one chunk, without ground to remove.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coordinate(-40.0F, 40.0F);
  Cloud scan(300'000);
  for (Point& p : scan) p = {coordinate(rng), coordinate(rng), coordinate(rng) / 20.0F, 1.0F};
  for (Mode mode : {Mode::kBaseline, Mode::kExt}) {
    EdgeConfig config = edgeConfig(mode);
    config.preprocess = PreprocessConfig{};
    config.madc.clustering.eps_m = 0.05;  // keep the clustering of random points quick
    const EdgeOutput output = process(EdgeNode(config), scan);
    ASSERT_GE(output.chunks.size(), 4U) << modeName(mode);
    EXPECT_TRUE(samePoints(reassemble(output.chunks).points, withoutIntensity(scan)));
    for (const PointChunk& chunk : output.chunks) {
      EXPECT_LT(toProto(chunk).ByteSizeLong(), kFourMiB) << modeName(mode) << " chunk " << chunk.chunk;
    }
  }
}

TEST(EdgeNode, ExtShipsTheMapAndPointsLabelledByTheLocalClustering) {
  EdgeConfig config = edgeConfig(Mode::kExt);
  config.max_points_per_chunk = 7000;
  const Cloud points = preprocessed(realScan(), config);
  const Clustering clustering = euclideanClusters(points, config.madc.clustering);

  const EdgeOutput output = process(EdgeNode(config), realScan());
  ASSERT_TRUE(output.map.has_value());
  EXPECT_EQ(output.map->header, expectedHeader());
  EXPECT_EQ(output.map->map.ellipsoidCount(), static_cast<std::size_t>(clustering.cluster_count));
  ASSERT_GT(output.chunks.size(), 1U);
  const Reassembled all = reassemble(output.chunks);
  EXPECT_TRUE(samePoints(all.points, withoutIntensity(points)));
  EXPECT_EQ(all.labels, clustering.labels);
  for (const PointChunk& chunk : output.chunks) EXPECT_EQ(chunk.labels.size(), chunk.points.size());
}

TEST(EdgeNode, ATranslatedPoseShiftsEveryEllipsoidCentreByTheTranslation) {
  // Crop and ground first, so that both runs see the same obstacles; then only the pose differs.
  const Cloud obstacles = preprocessed(realScan(), edgeConfig(Mode::kMadc));
  EdgeConfig at_origin = edgeConfig(Mode::kMadc);
  at_origin.preprocess = PreprocessConfig{};
  EdgeConfig moved = at_origin;
  const Eigen::Vector3d translation(12.5, -7.25, 1.5);
  moved.preprocess.sensor_to_common = Eigen::Translation3d(translation) * Eigen::Isometry3d::Identity();

  const EdgeOutput reference = process(EdgeNode(at_origin), obstacles);
  const EdgeOutput shifted = process(EdgeNode(moved), obstacles);
  ASSERT_TRUE(reference.map && shifted.map);
  ASSERT_GT(reference.map->map.ellipsoidCount(), 0U);
  ASSERT_EQ(shifted.map->map.objects.size(), reference.map->map.objects.size());
  for (std::size_t i = 0; i < reference.map->map.objects.size(); ++i) {
    const Ellipsoid& a = reference.map->map.objects[i].ellipsoids.at(0);
    const Ellipsoid& b = shifted.map->map.objects[i].ellipsoids.at(0);
    ASSERT_EQ(a.id, b.id);
    EXPECT_EQ(a.point_count, b.point_count);
    EXPECT_LT((b.center - a.center - translation).norm(), 1e-4) << toString(a.id);
    EXPECT_LT((b.shape - a.shape).norm(), 1e-3) << toString(a.id);
  }
}

TEST(EdgeNode, ARotatedPoseTurnsTheMapWithIt) {
  const Cloud obstacles = preprocessed(realScan(), edgeConfig(Mode::kMadc));
  EdgeConfig at_origin = edgeConfig(Mode::kMadc);
  at_origin.preprocess = PreprocessConfig{};
  EdgeConfig turned = at_origin;
  const Eigen::Isometry3d pose = sectorPose(SectorSplit{4, 0, 0.0});  // 45 degrees about z
  turned.preprocess.sensor_to_common = pose;

  const EdgeOutput reference = process(EdgeNode(at_origin), obstacles);
  const EdgeOutput output = process(EdgeNode(turned), obstacles);
  ASSERT_TRUE(reference.map && output.map);
  ASSERT_EQ(output.map->map.objects.size(), reference.map->map.objects.size());
  for (std::size_t i = 0; i < reference.map->map.objects.size(); ++i) {
    const Ellipsoid& a = reference.map->map.objects[i].ellipsoids.at(0);
    const Ellipsoid& b = output.map->map.objects[i].ellipsoids.at(0);
    EXPECT_LT((b.center - pose * a.center).norm(), 1e-4) << toString(a.id);
  }
}

TEST(EdgeNode, AScanWithNothingLeftGivesAnEmptyMapNotAnError) {
  const Cloud far_away = {{500.0F, 0.0F, 0.0F, 0.0F}, {0.0F, 500.0F, 0.0F, 0.0F}, {1.0F, 1.0F, 0.0F, 0.0F}};
  for (const Cloud& scan : {Cloud{}, far_away}) {
    for (Mode mode : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
      const EdgeOutput output = process(EdgeNode(edgeConfig(mode)), scan);
      EXPECT_EQ(output.points_in, scan.size());
      EXPECT_EQ(output.points_out, 0U);
      if (mode != Mode::kBaseline) {
        ASSERT_TRUE(output.map.has_value()) << modeName(mode);
        EXPECT_EQ(output.map->header, expectedHeader());
        EXPECT_TRUE(output.map->map.objects.empty());
      }
      if (mode != Mode::kMadc) {
        // One empty chunk still tells the parent that this node reported the epoch.
        ASSERT_EQ(output.chunks.size(), 1U) << modeName(mode);
        EXPECT_EQ(output.chunks[0].total_points, 0U);
        EXPECT_EQ(output.chunks[0].chunk_count, 1U);
        EXPECT_TRUE(output.chunks[0].points.empty());
      }
    }
  }
}

TEST(EdgeNode, InvalidGroundSettingsAreAnError) {
  EdgeConfig config = edgeConfig(Mode::kMadc);
  config.preprocess.ground->max_tilt_deg = 0.0;
  Expected<EdgeOutput> output = EdgeNode(config).processFrame(realScan(), kFrame, kSensorTimeNs);
  ASSERT_FALSE(output.ok());
  EXPECT_EQ(output.error().code, ErrorCode::kInvalidArgument);
}

TEST(EdgeNode, AVirtualSensorPoseIsTheSensorPoseAfterTheSectorRotation) {
  SensorConfig sensor;
  sensor.pose = Eigen::Translation3d(3.0, 4.0, 1.8) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(sensorToCommon(sensor).isApprox(sensor.pose));
  sensor.split = SectorSplit{6, 4, 10.0};
  EXPECT_TRUE(sensorToCommon(sensor).isApprox(sensor.pose * sectorPose(*sensor.split)));

  // A sector view put through its pose lands where the whole scan put through the sensor pose does.
  const Cloud view = sectorView(realScan(), *sensor.split);
  ASSERT_FALSE(view.empty());
  const Eigen::Vector3d via_sector = sensorToCommon(sensor) * view.front().xyz().cast<double>();
  const Eigen::Vector3d scan_point = sectorPose(*sensor.split) * view.front().xyz().cast<double>();
  EXPECT_LT((via_sector - sensor.pose * scan_point).norm(), 1e-9);
}

// A cube of m^3 lattice points of edge `edge_m` centred on `centre`, in the sensor frame.
Cloud cube(const Eigen::Vector3d& centre, double edge_m, int m) {
  Cloud points;
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      for (int k = 0; k < m; ++k) {
        const Eigen::Vector3d p = centre + edge_m * (Eigen::Vector3d(i, j, k) / (m - 1) - Eigen::Vector3d::Constant(0.5));
        points.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 1.0F});
      }
    }
  }
  return points;
}

Cloud joined(Cloud a, const Cloud& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// The oracle: mean and sample covariance of points moved into the common frame.
std::pair<Eigen::Vector3d, Eigen::Matrix3d> meanAndCovariance(const Cloud& points, const Eigen::Isometry3d& pose) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Point& p : points) mean += pose * Eigen::Vector3d(p.x, p.y, p.z);
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const Point& p : points) {
    const Eigen::Vector3d d = pose * Eigen::Vector3d(p.x, p.y, p.z) - mean;
    covariance += d * d.transpose();
  }
  return {mean, covariance / static_cast<double>(points.size() - 1)};
}

EdgeConfig displacementConfig(Mode mode, const Eigen::Isometry3d& pose) {
  EdgeConfig config = edgeConfig(mode);
  config.name = "edge-7";
  config.preprocess = PreprocessConfig{};  // no ground in these scenes
  config.preprocess.sensor_to_common = pose;
  tracking::DisplacementParams params;
  params.voxel_m = 0.1;
  params.neighbour_m = 0.15;
  params.min_neighbours = 3;
  params.min_points = 5;
  config.displacement = params;
  return config;
}

TEST(EdgeNode, DisplacementCentroidsAreTheMovedObjectsInTheCommonFrameFromTheSecondScanOn) {
  const Eigen::Isometry3d pose = Eigen::Translation3d(3.0, -2.0, 1.5) * Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ());
  // A box standing still and one that moves 1 m between the scans (0.5 m boxes, 216 points each).
  const Cloud still = cube({6.0, 0.0, 0.0}, 0.5, 6);
  const Cloud before = cube({0.0, 4.0, 0.0}, 0.5, 6);
  const Cloud after = cube({1.0, 4.0, 0.0}, 0.5, 6);
  EdgeNode edge(displacementConfig(Mode::kMadc, pose));

  const auto first = edge.processFrame(joined(still, before), 10, 1'000);
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_FALSE(first->centroids.has_value()) << "the first scan has no previous one: all of it would be displacement";
  EXPECT_TRUE(first->displacement_seconds.has_value());
  EXPECT_EQ(first->map->map.objects.size(), 2U) << "the map is as without displacement";

  const auto second = edge.processFrame(joined(still, after), 11, 2'000);
  ASSERT_TRUE(second.ok()) << second.error().message;
  ASSERT_TRUE(second->centroids.has_value());
  const tracking::CentroidFrame& frame = *second->centroids;
  EXPECT_EQ(frame.edge, "edge-7");
  EXPECT_EQ(frame.epoch, 11U);
  EXPECT_EQ(frame.time_ns, 2'000);
  EXPECT_LT((frame.sensor_position - Eigen::Vector3d(3.0, -2.0, 1.5)).norm(), 1e-12);
  ASSERT_EQ(frame.centroids.size(), 1U) << "only the box that moved";
  const auto [mean, covariance] = meanAndCovariance(after, pose);
  EXPECT_LT((frame.centroids[0].position - mean).norm(), 1e-5);
  EXPECT_LT((frame.centroids[0].covariance - covariance).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_EQ(frame.centroids[0].point_count, after.size());

  // Nothing moved since: a frame with no centroids (the tracker learns the edge is alive).
  const auto third = edge.processFrame(joined(still, after), 12, 3'000);
  ASSERT_TRUE(third.ok() && third->centroids.has_value());
  EXPECT_TRUE(third->centroids->centroids.empty());
}

TEST(EdgeNode, ABaselineShippingRawScansFindsCentroidsInTheCleanedScan) {
  // A box moving inside the crop and one moving outside it: only the first is the edge's.
  EdgeConfig config = displacementConfig(Mode::kBaseline, Eigen::Isometry3d::Identity());
  config.ship_raw = true;
  config.preprocess.crop = CropBox{{-10.0, -10.0, -3.0}, {10.0, 10.0, 3.0}};
  EdgeNode edge(config);
  const auto first = edge.processFrame(joined(cube({0.0, 4.0, 0.0}, 0.5, 6), cube({30.0, 0.0, 0.0}, 0.5, 6)), 1, 1);
  ASSERT_TRUE(first.ok()) << first.error().message;
  const Cloud inside = cube({1.0, 4.0, 0.0}, 0.5, 6);
  const auto second = edge.processFrame(joined(inside, cube({31.0, 0.0, 0.0}, 0.5, 6)), 2, 2);
  ASSERT_TRUE(second.ok()) << second.error().message;
  EXPECT_EQ(second->points_out, 2 * inside.size()) << "the scan ships whole";
  ASSERT_TRUE(second->centroids.has_value());
  ASSERT_EQ(second->centroids->centroids.size(), 1U);
  EXPECT_LT((second->centroids->centroids[0].position - meanAndCovariance(inside, Eigen::Isometry3d::Identity()).first).norm(), 1e-5);
}

TEST(EdgeNode, InvalidDisplacementSettingsAreAnErrorOnEveryFrame) {
  EdgeConfig config = displacementConfig(Mode::kMadc, Eigen::Isometry3d::Identity());
  config.displacement->min_points = 1;
  EdgeNode edge(config);
  for (std::uint64_t frame = 0; frame < 2; ++frame) {
    const auto output = edge.processFrame(cube({0.0, 4.0, 0.0}, 0.5, 6), frame, 1);
    ASSERT_FALSE(output.ok());
    EXPECT_NE(output.error().message.find("min_points"), std::string::npos) << output.error().message;
  }
}

TEST(EdgeNode, ConfigFromTheTopologyUsesItsModeSettingsAndTheNodePose) {
  TopologyConfig topology;
  topology.mode = Mode::kExt;
  topology.madc.clustering.eps_m = 0.5;
  topology.preprocess.crop = CropBox{};
  topology.max_message_bytes = 1U << 20;
  NodeConfig node;
  node.id = 3;
  node.name = "edge-3";
  node.sensor = SensorConfig{};
  node.sensor->pose = Eigen::Translation3d(1.0, 2.0, 3.0) * Eigen::Isometry3d::Identity();

  const EdgeConfig config = edgeConfigFor(topology, node);
  EXPECT_EQ(config.node, 3U);
  EXPECT_EQ(config.mode, Mode::kExt);
  EXPECT_EQ(config.madc.clustering.eps_m, 0.5);
  EXPECT_TRUE(config.preprocess.crop.has_value());
  EXPECT_TRUE(config.preprocess.sensor_to_common.isApprox(node.sensor->pose));
  EXPECT_EQ(config.max_points_per_chunk, (1U << 20) / 2 / 16);  // half of a 1 MiB limit at 16 bytes a point

  topology.max_message_bytes = 64U << 20;
  EXPECT_EQ(edgeConfigFor(topology, node).max_points_per_chunk, kDefaultMaxPointsPerChunk);
  EXPECT_EQ(config.name, "edge-3");
  EXPECT_FALSE(config.displacement.has_value());
  node.displacement = DisplacementNodeConfig{"tracker", tracking::DisplacementParams::outdoor()};
  EXPECT_EQ(edgeConfigFor(topology, node).displacement, tracking::DisplacementParams::outdoor());

  // Exact clustering unless the sensor says otherwise; sensor-aware clustering takes the model's
  // beam table and the sensor's pose in the common frame (the frame the edge clusters in).
  EXPECT_FALSE(config.madc.sensor_links.has_value());
  node.sensor->clustering = ClusteringMode::kSensor;
  node.sensor->model = "VLP-16";
  node.sensor->split = SectorSplit{4, 1, 10.0};
  const EdgeConfig sensor_aware = edgeConfigFor(topology, node);
  ASSERT_TRUE(sensor_aware.madc.sensor_links.has_value());
  const auto vlp16 = lidarModel("VLP-16");
  ASSERT_TRUE(vlp16.ok());
  EXPECT_EQ(sensor_aware.madc.sensor_links->beams.elevations_deg, vlp16->elevations_deg);
  EXPECT_DOUBLE_EQ(sensor_aware.madc.sensor_links->beams.azimuth_step_deg, 0.2);
  EXPECT_TRUE(sensor_aware.madc.sensor_links->sensor_pose.isApprox(sensorToCommon(*node.sensor)));
  EXPECT_TRUE(sensor_aware.madc.sensor_links->sensor_pose.isApprox(sensor_aware.preprocess.sensor_to_common));
}

}  // namespace
}  // namespace fogmap
