// The live view's events against hand-computed answers: the shadow of an ellipsoid, the sensors'
// headings, geofence occupancy, node health and track trails.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "common/base/angles.hpp"
#include "common/config/camera_node.hpp"
#include "tests/support/global_maps.hpp"
#include "view/live_view.hpp"

namespace fogmap::view {
namespace {

using nlohmann::json;
using test_support::globalMapWith;

Ellipsoid ellipsoidWith(const Eigen::Matrix3d& shape) {
  Ellipsoid e;
  e.center = {1.0, 2.0, 3.0};
  e.shape = shape;
  return e;
}

TEST(GroundEllipse, AnAxisAlignedEllipsoidCastsItsHorizontalSemiAxes) {
  const GroundEllipse g = groundEllipse(ellipsoidWith(Eigen::Vector3d(1.0, 4.0, 9.0).asDiagonal()));
  EXPECT_NEAR(g.a, 2.0, 1e-12);  // along y
  EXPECT_NEAR(g.b, 1.0, 1e-12);
  EXPECT_NEAR(std::abs(g.angle_rad), std::numbers::pi / 2, 1e-12);
  EXPECT_EQ(g.centre, Eigen::Vector2d(1.0, 2.0));
}

TEST(GroundEllipse, AYawedEllipsoidKeepsItsYawAndATiltedOneCastsItsWholeShadow) {
  const Eigen::Matrix3d yaw = Eigen::AngleAxisd(30.0 * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3d shape = yaw * Eigen::Vector3d(9.0, 1.0, 1.0).asDiagonal() * yaw.transpose();
  const GroundEllipse g = groundEllipse(ellipsoidWith(shape));
  EXPECT_NEAR(g.a, 3.0, 1e-12);
  EXPECT_NEAR(g.b, 1.0, 1e-12);
  EXPECT_NEAR(g.angle_rad, 30.0 * kDegToRad, 1e-12);
  // A rod of half-length 2 tilted 60 degrees up from +x: its shadow reaches 2 cos 60 = 1 along x,
  // and the rod's 0.1 m radius across (y); the brute-force oracle: the extreme x of its surface.
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-60.0 * kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d rod = tilt * Eigen::Vector3d(4.0, 0.01, 0.01).asDiagonal() * tilt.transpose();
  const GroundEllipse s = groundEllipse(ellipsoidWith(rod));
  double reach = 0.0;
  for (int i = 0; i <= 2000; ++i) {
    for (int j = 0; j <= 400; ++j) {
      const double u = std::numbers::pi * i / 1000.0;
      const double v = std::numbers::pi * j / 400.0;
      const Eigen::Vector3d unit(std::cos(u) * std::sin(v), std::sin(u) * std::sin(v), std::cos(v));
      const Eigen::Vector3d p = tilt * Eigen::Vector3d(2.0, 0.1, 0.1).cwiseProduct(unit);
      reach = std::max(reach, p.x());
    }
  }
  EXPECT_NEAR(s.a, reach, 1e-3);
  EXPECT_NEAR(s.b, 0.1, 1e-9);
  EXPECT_NEAR(s.angle_rad, 0.0, 1e-9);
}

TEST(FenceBoxes, ParsesBoxesAndNamesWhatIsWrong) {
  const auto fences = parseFenceBoxes("gate=0,0,0,5,5,3;yard=-10,-10,0,-5,-2,2.5");
  ASSERT_TRUE(fences) << fences.error().message;
  ASSERT_EQ(fences->size(), 2U);
  EXPECT_EQ((*fences)[1].name, "yard");
  EXPECT_EQ((*fences)[1].max, Eigen::Vector3d(-5, -2, 2.5));
  EXPECT_TRUE(parseFenceBoxes("")->empty());
  for (const auto& [text, names] : std::vector<std::pair<std::string, std::string>>{
           {"=0,0,0,1,1,1", "NAME="},
           {"gate=0,0,0,1,1", "6 numbers"},
           {"gate=0,0,0,1,x,1", "'x'"},
           {"gate=0,0,0,1,nan,1", "'nan'"},
           {"gate=0,0,0,1,0,1", "below the maximum"},
           {"gate=0,0,0,1,1,1;gate=2,2,2,3,3,3", "twice"}}) {
    const auto bad = parseFenceBoxes(text);
    ASSERT_FALSE(bad) << text;
    EXPECT_NE(bad.error().message.find(names), std::string::npos) << bad.error().message;
  }
}

TopologyConfig twoSensorTopology() {
  TopologyConfig t;
  t.name = "view-test";
  NodeConfig root;
  root.id = 0;
  root.name = "root";
  root.role = Role::kAggregator;
  NodeConfig edge;
  edge.id = 1;
  edge.name = "edge-1";
  edge.parent = "root";
  edge.sensor = SensorConfig{};
  edge.sensor->pose = Eigen::Translation3d(4, 5, 1.8) * Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ());
  NodeConfig camera;
  camera.id = 7;
  camera.name = "cam-1";
  camera.role = Role::kDetection;
  CameraNodeConfig c;
  // The camera at (1, 2, 1.5) looking along -x: its z axis is the common frame's -x.
  Eigen::Matrix3d camera_to_world;
  camera_to_world.col(0) = Eigen::Vector3d(0, 1, 0);
  camera_to_world.col(1) = Eigen::Vector3d(0, 0, -1);
  camera_to_world.col(2) = Eigen::Vector3d(-1, 0, 0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = camera_to_world;
  pose.translation() = Eigen::Vector3d(1, 2, 1.5);
  c.calibration.world_to_camera = pose.inverse();
  camera.camera = c;
  t.nodes = {root, edge, camera};
  return t;
}

TEST(LiveView, TheConfigHasEachSensorWhereItIsAndWhereItLooks) {
  const LiveView live(viewConfigOf(twoSensorTopology(), {}));
  const json config = json::parse(live.configEvent());
  EXPECT_EQ(config["topology"], "view-test");
  EXPECT_FALSE(config["has_tracker"].get<bool>());
  ASSERT_EQ(config["sensors"].size(), 2U);
  EXPECT_EQ(config["sensors"][0]["name"], "edge-1");
  EXPECT_EQ(config["sensors"][0]["kind"], "lidar");
  EXPECT_DOUBLE_EQ(config["sensors"][0]["x"].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(config["sensors"][0]["heading_deg"].get<double>(), 90.0);
  EXPECT_EQ(config["sensors"][1]["kind"], "camera");
  EXPECT_DOUBLE_EQ(config["sensors"][1]["y"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(std::abs(config["sensors"][1]["heading_deg"].get<double>()), 180.0);
  EXPECT_EQ(config["nodes"].size(), 3U);
}

TEST(LiveView, AMapEventHasTheObjectsTheOccupiedGeofencesAndEachNodesLastEpoch) {
  const auto fences = parseFenceBoxes("gate=0,0,0,2,2,2;far=50,50,0,60,60,2");
  LiveView live(viewConfigOf(twoSensorTopology(), *fences));
  GlobalMapMessage first = globalMapWith(1'700'000'000'123'456'789, {{1, 1, 1}, {10, 0, 1}});
  first.header.epoch = 41;
  first.header.contributing_nodes = {1};
  first.published_time_ns = 1'700'000'000'200'000'000;
  json map = json::parse(live.mapEvent(first));
  EXPECT_EQ(map["epoch"], 41);
  EXPECT_DOUBLE_EQ(map["published_ms"].get<double>(), 1'700'000'000'200.0);
  EXPECT_DOUBLE_EQ(map["sensor_ms"].get<double>(), 1'700'000'000'123.456);
  ASSERT_EQ(map["objects"].size(), 2U);
  const json& o = map["objects"][0];
  EXPECT_EQ(o["points"], 50);
  EXPECT_EQ(o["sensors"], json::array({"edge-1"}));
  EXPECT_TRUE(o["class"].is_null());
  EXPECT_TRUE(o["box"].is_null());
  ASSERT_EQ(o["ellipses"].size(), 1U);
  EXPECT_DOUBLE_EQ(o["ellipses"][0]["a"].get<double>(), 0.3);
  EXPECT_DOUBLE_EQ(o["ellipses"][0]["cx"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(o["extent"]["min"][0].get<double>(), 0.7);
  // The ball at (1, 1, 1) is inside the gate; nothing is in the far fence.
  EXPECT_EQ(map["geofences"][0]["name"], "gate");
  EXPECT_TRUE(map["geofences"][0]["occupied"].get<bool>());
  EXPECT_EQ(map["geofences"][0]["objects"], json::array({0}));
  EXPECT_FALSE(map["geofences"][1]["occupied"].get<bool>());
  ASSERT_EQ(map["nodes"].size(), 1U);
  EXPECT_FALSE(map["nodes"][0]["missing"].get<bool>());
  EXPECT_EQ(map["nodes"][0]["last_epoch"], 41);

  // The edge goes missing: its last epoch stays 41; a node never seen has none.
  GlobalMapMessage second = globalMapWith(2, {});
  second.header.epoch = 42;
  second.header.missing_nodes = {1, 9};
  map = json::parse(live.mapEvent(second));
  ASSERT_EQ(map["nodes"].size(), 2U);
  EXPECT_EQ(map["nodes"][0]["name"], "edge-1");
  EXPECT_TRUE(map["nodes"][0]["missing"].get<bool>());
  EXPECT_EQ(map["nodes"][0]["last_epoch"], 41);
  EXPECT_EQ(map["nodes"][1]["name"], "node 9");
  EXPECT_TRUE(map["nodes"][1]["last_epoch"].is_null());
  EXPECT_FALSE(map["geofences"][0]["occupied"].get<bool>());
}

TEST(LiveView, AMapEventCarriesTheObjectsBoxAndClass) {
  LiveView live(viewConfigOf(twoSensorTopology(), {}));
  GlobalMapMessage g = globalMapWith(1, {{3, 4, 0.8}});
  OrientedBox box;
  box.centre = {3, 4, 0.8};
  box.length = 4.5;
  box.width = 1.8;
  box.height = 1.6;
  box.yaw = 30.0 * kDegToRad;
  g.map.objects[0].ellipsoids[0].box = box;
  g.map.objects[0].ellipsoids[0].label = ObjectLabel{ObjectClass::kCar, 0.9};
  const json o = json::parse(live.mapEvent(g))["objects"][0];
  EXPECT_EQ(o["class"], "car");
  EXPECT_DOUBLE_EQ(o["confidence"].get<double>(), 0.9);
  EXPECT_DOUBLE_EQ(o["box"]["length"].get<double>(), 4.5);
  EXPECT_DOUBLE_EQ(o["box"]["yaw_deg"].get<double>(), 30.0);
  EXPECT_DOUBLE_EQ(o["box"]["zmin"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(o["box"]["zmax"].get<double>(), 1.6);
}

tracking::Track trackAt(std::uint64_t id, double x, double y) {
  tracking::Track t;
  t.id = id;
  t.state = tracking::TrackState::kConfirmed;
  t.position = {x, y};
  t.velocity = {1.0, 0.0};
  t.covariance = Eigen::Matrix2d::Identity() * 0.04;
  return t;
}

TEST(LiveView, TracksKeepBoundedTrailsThatEndWithTheTrack) {
  LiveView live(viewConfigOf(twoSensorTopology(), {}), /*trail_points=*/3, /*max_trails=*/1);
  json tracks;
  for (int k = 0; k < 5; ++k) {
    tracking::TrackSnapshot s;
    s.published_time_ns = 1'000'000'000LL * k;
    s.tracks = {trackAt(7, k, 0), trackAt(8, 0, k)};
    tracks = json::parse(live.tracksEvent(s));
  }
  ASSERT_EQ(tracks["tracks"].size(), 2U);
  EXPECT_EQ(tracks["tracks"][0]["id"], 7);
  EXPECT_EQ(tracks["tracks"][0]["state"], "confirmed");
  EXPECT_DOUBLE_EQ(tracks["tracks"][0]["sigma_m"].get<double>(), 0.2);
  EXPECT_EQ(tracks["tracks"][0]["trail"], json::parse("[[2,0],[3,0],[4,0]]"));  // the last 3
  EXPECT_TRUE(tracks["tracks"][1]["trail"].empty());  // beyond max_trails: drawn without one
  EXPECT_DOUBLE_EQ(tracks["published_ms"].get<double>(), 4000.0);
  // Track 7 ends: its trail goes; a track that comes back under its id starts a new one.
  tracking::TrackSnapshot s;
  s.tracks = {trackAt(8, 0, 9)};
  tracks = json::parse(live.tracksEvent(s));
  EXPECT_EQ(tracks["tracks"][0]["trail"], json::parse("[[0,9]]"));
  s.tracks = {trackAt(7, 5, 5)};
  tracks = json::parse(live.tracksEvent(s));
  EXPECT_EQ(tracks["tracks"][0]["trail"], json::parse("[[5,5]]"));
}

TEST(LiveView, TheStatusSaysWhichLinkIsDownAndWhy) {
  const LiveView live(viewConfigOf(twoSensorTopology(), {}));
  const json status = json::parse(live.statusEvent({false, "127.0.0.1:5000", "connection refused"},
                                                   LinkState{true, "127.0.0.1:5010", ""}, 3, 2'000'000'000));
  EXPECT_FALSE(status["root"]["connected"].get<bool>());
  EXPECT_EQ(status["root"]["detail"], "connection refused");
  EXPECT_TRUE(status["tracker"]["connected"].get<bool>());
  EXPECT_EQ(status["skipped_events"], 3);
  EXPECT_DOUBLE_EQ(status["server_ms"].get<double>(), 2000.0);
  EXPECT_TRUE(json::parse(live.statusEvent({}, std::nullopt, 0, 0))["tracker"].is_null());
}

}  // namespace
}  // namespace fogmap::view
