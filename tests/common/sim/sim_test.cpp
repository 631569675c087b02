// The scene simulator against analytic answers: ray-box, ray-cylinder and ray-ground distances,
// occlusion, the makers' beam tables, determinism across thread counts, per-point truth on the
// labelled surfaces, motion, the scene format and the generators.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>

#include "common/perception/clustering.hpp"
#include "common/perception/preprocess.hpp"
#include "common/scoring/object_match.hpp"
#include "common/scoring/rand_index.hpp"
#include "common/sim/footprint.hpp"
#include "common/sim/generators.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/sim/raycaster.hpp"
#include "common/sim/scene.hpp"
#include "tests/support/scene_raycaster.hpp"

namespace fogmap::sim {
namespace {

constexpr double kTol = 1e-4;  // Embree works in float: metres to about 1e-5 at 10 m

SceneObject boxObject(std::uint32_t id, Eigen::Vector2d xy, Eigen::Vector3d size, double yaw_deg = 0.0) {
  SceneObject o;
  o.id = id;
  o.name = "box-" + std::to_string(id);
  o.label = "crate";
  o.xy = xy;
  o.yaw_deg = yaw_deg;
  o.parts = {{Shape::kBox, Eigen::Vector3d::Zero(), size, 0.0}};
  return o;
}

SceneObject cylinderObject(std::uint32_t id, Eigen::Vector2d xy, double radius, double height) {
  SceneObject o;
  o.id = id;
  o.name = "cyl-" + std::to_string(id);
  o.label = "person";
  o.xy = xy;
  o.parts = {{Shape::kCylinder, Eigen::Vector3d::Zero(), {2 * radius, 2 * radius, height}, 0.0}};
  return o;
}

Scene sceneWith(std::vector<SceneObject> objects) {
  Scene s;
  s.extent_m = 100.0;
  s.objects = std::move(objects);
  LidarConfig l;
  l.name = "l1";
  s.lidars = {l};
  return s;
}

using test_support::raycaster;

TEST(SimBeams, TablesHaveTheMakersRingsAndAngles) {
  struct Expect {
    const char* name;
    int rings;
    double top, bottom;
  };
  for (const Expect& e : {Expect{"VLP-16", 16, 15.0, -15.0}, Expect{"HDL-32E", 32, 10.67, -30.67},
                          Expect{"HDL-64E", 64, 2.0, -24.33}, Expect{"OS1-64", 64, 16.6, -16.6}}) {
    const auto m = lidarModel(e.name);
    ASSERT_TRUE(m.ok()) << e.name;
    EXPECT_EQ(m->rings(), e.rings) << e.name;
    const auto [lo, hi] = std::minmax_element(m->elevations_deg.begin(), m->elevations_deg.end());
    EXPECT_NEAR(*hi, e.top, 0.005) << e.name;  // the makers print two decimals
    EXPECT_NEAR(*lo, e.bottom, 0.005) << e.name;
    EXPECT_GT(m->azimuth_steps, 1000) << e.name;
    EXPECT_EQ(std::set<double>(m->elevations_deg.begin(), m->elevations_deg.end()).size(), m->elevations_deg.size())
        << e.name << ": two lasers at one angle";
  }
  // The HDL-64E's two blocks: 1/3 degree spacing above -8.33, 1/2 degree below.
  const auto hdl64 = lidarModel("HDL-64E");
  EXPECT_NEAR(hdl64->elevations_deg[0] - hdl64->elevations_deg[1], 1.0 / 3.0, 1e-9);
  EXPECT_NEAR(hdl64->elevations_deg[40] - hdl64->elevations_deg[41], 0.5, 1e-9);
  EXPECT_NEAR(hdl64->raysPerFrame(), 131072, 0);
  const auto unknown = lidarModel("HDL-128");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.error().message.find("known: VLP-16, HDL-32E, HDL-64E, OS1-64"), std::string::npos);
}

TEST(SimRaycast, RayHitsABoxFaceAtTheAnalyticDistance) {
  const auto r = raycaster(sceneWith({boxObject(3, {10, 0}, {2, 2, 2}), boxObject(4, {0, 20}, {2, 2, 2}, 45.0)}));
  const auto front = r.cast({0, 0, 1}, {1, 0, 0}, 100);
  ASSERT_TRUE(front.has_value());
  EXPECT_NEAR(front->distance_m, 9.0, kTol);
  EXPECT_EQ(front->object, 3U);
  // Oblique: the ray meets the face x = 9 at y = 9 tan(5 deg).
  const double a = 5.0 * M_PI / 180.0;
  const auto oblique = r.cast({0, 0, 1}, {std::cos(a), std::sin(a), 0}, 100);
  ASSERT_TRUE(oblique.has_value());
  EXPECT_NEAR(oblique->distance_m, 9.0 / std::cos(a), kTol);
  // Turned 45 degrees: the nearest edge is sqrt(2) from the centre.
  const auto edge = r.cast({0, 0, 1}, {0, 1, 0}, 100);
  ASSERT_TRUE(edge.has_value());
  EXPECT_NEAR(edge->distance_m, 20.0 - std::sqrt(2.0), kTol);
  EXPECT_EQ(edge->object, 4U);
  // Over the box: the top face at z = 2.
  const auto top = r.cast({10, 0.3, 7}, {0, 0, -1}, 100);
  ASSERT_TRUE(top.has_value());
  EXPECT_NEAR(top->distance_m, 5.0, kTol);
}

TEST(SimRaycast, RayHitsACylinderAtTheAnalyticDistance) {
  const auto r = raycaster(sceneWith({cylinderObject(7, {5, 0}, 0.5, 2.0)}));
  const auto side = r.cast({0, 0, 1}, {1, 0, 0}, 100);
  ASSERT_TRUE(side.has_value());
  EXPECT_NEAR(side->distance_m, 4.5, kTol);
  EXPECT_EQ(side->object, 7U);
  // Off-axis at lateral offset b: the chord enters at 5 - sqrt(r^2 - b^2).
  const Eigen::Vector3d dir(1, 0, 0);
  const auto offset = r.cast({0, 0.3, 1}, dir, 100);
  ASSERT_TRUE(offset.has_value());
  EXPECT_NEAR(offset->distance_m, 5.0 - std::sqrt(0.25 - 0.09), kTol);
  // Past the radius: the ground far away, not the cylinder.
  const auto miss = r.cast({0, 0.6, 1}, dir, 100);
  EXPECT_FALSE(miss.has_value() && miss->object == 7U);
  // The cap: from above onto z = 2.
  const auto cap = r.cast({5.2, 0.1, 10}, {0, 0, -1}, 100);
  ASSERT_TRUE(cap.has_value());
  EXPECT_NEAR(cap->distance_m, 8.0, kTol);
  EXPECT_EQ(cap->object, 7U);
  // Over the top: a ray at z = 2.5 passes above.
  const auto over = r.cast({0, 0, 2.5}, dir, 100);
  EXPECT_FALSE(over.has_value());
}

TEST(SimRaycast, GroundPlanesTiltAndStepAtTheAnalyticDistance) {
  Scene flat = sceneWith({});
  const auto r = raycaster(flat);
  const double e = -10.0 * M_PI / 180.0;
  const auto ground = r.cast({0, 0, 2}, {std::cos(e), 0, std::sin(e)}, 100);
  ASSERT_TRUE(ground.has_value());
  EXPECT_NEAR(ground->distance_m, 2.0 / std::sin(-e), kTol);
  EXPECT_EQ(ground->object, kGroundId);

  Scene tilted = sceneWith({});
  tilted.ground.tilt_deg = 5.0;  // z = tan(5 deg) x
  const auto t = raycaster(tilted).cast({10, 0, 3}, {0, 0, -1}, 100);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(t->distance_m, 3.0 - 10.0 * std::tan(5.0 * M_PI / 180.0), kTol);

  Scene step = sceneWith({});
  step.ground.step_x_m = 4.0;
  step.ground.step_height_m = 0.5;
  const auto rs = raycaster(step);
  EXPECT_NEAR(rs.cast({6, 0, 3}, {0, 0, -1}, 100)->distance_m, 2.5, kTol);  // on the step
  EXPECT_NEAR(rs.cast({2, 0, 3}, {0, 0, -1}, 100)->distance_m, 3.0, kTol);  // before it
  EXPECT_NEAR(rs.cast({0, 0, 0.25}, {1, 0, 0}, 100)->distance_m, 4.0, kTol);  // the riser
  // Objects stand on the step.
  const auto on_step = raycaster([&] {
                         Scene s = step;
                         s.objects = {boxObject(2, {8, 0}, {1, 1, 1})};
                         return s;
                       }())
                           .cast({8, 0, 5}, {0, 0, -1}, 100);
  EXPECT_NEAR(on_step->distance_m, 5.0 - 1.5, kTol);
}

TEST(SimScan, AnObjectBehindAnotherGetsNoPoints) {
  const SceneObject wall = boxObject(1, {5, 0}, {2, 2, 3});
  const SceneObject hidden = boxObject(2, {10, 0}, {0.5, 0.5, 0.5});
  Scene scene = sceneWith({wall, hidden});
  scene.lidars[0].pose.translation() = Eigen::Vector3d(0, 0, 1);
  scene.lidars[0].range_noise_m = 0.0;
  const auto frame = raycaster(scene).scan(scene.lidars[0], 1, 0);
  ASSERT_TRUE(frame.ok());
  const auto count = [](const SimFrame& f, std::uint32_t id) { return std::count(f.truth.begin(), f.truth.end(), id); };
  EXPECT_GT(count(*frame, 1), 50);
  EXPECT_EQ(count(*frame, 2), 0) << "the box behind the wall was seen";
  // Without the wall the box is seen: the test can fail.
  Scene open = sceneWith({hidden});
  open.lidars = scene.lidars;
  EXPECT_GT(count(*raycaster(open).scan(open.lidars[0], 1, 0), 2), 5);
}

// The distance from p to the surface of a part of `object` at time t (the smallest over parts).
double surfaceDistance(const SceneObject& object, const Ground& ground, double t, const Eigen::Vector3d& p) {
  const ObjectPose pose = poseAt(object, t);
  double best = 1e300;
  for (const Part& part : object.parts) {
    const Eigen::Vector2d centre = pose.xy + Eigen::Rotation2Dd(pose.yaw_rad) * part.at.head<2>();
    const double z0 = ground.heightAt(pose.xy.x()) + part.at.z();
    if (part.shape == Shape::kCylinder) {
      const double radial = (p.head<2>() - centre).norm() - part.size.x() / 2.0;
      const double vertical = std::max(z0 - p.z(), p.z() - (z0 + part.size.z()));
      best = std::min(best, std::max(radial, vertical) > 0 ? std::hypot(std::max(radial, 0.0), std::max(vertical, 0.0))
                                                           : -std::max(radial, vertical));
    } else {
      const Eigen::Vector2d local =
          Eigen::Rotation2Dd(-(pose.yaw_rad + part.yaw_deg * M_PI / 180.0)) * (p.head<2>() - centre);
      const Eigen::Vector3d q(std::abs(local.x()) - part.size.x() / 2, std::abs(local.y()) - part.size.y() / 2,
                              std::abs(p.z() - (z0 + part.size.z() / 2)) - part.size.z() / 2);
      const double outside = q.cwiseMax(0.0).norm();
      best = std::min(best, outside > 0 ? outside : -q.maxCoeff());
    }
  }
  return best;
}

TEST(SimScan, EveryPointLiesOnTheSurfaceOfItsLabelledObject) {
  const Scene scene = randomScene(30, 3, 11);
  const auto r = raycaster(scene, 0.0);
  std::size_t checked = 0;
  for (const LidarConfig& lidar : scene.lidars) {
    const auto frame = r.scan(lidar, scene.seed, 0);
    ASSERT_TRUE(frame.ok());
    ASSERT_EQ(frame->points.size(), frame->truth.size());
    const double bound = 6 * lidar.range_noise_m + 1e-3;
    for (std::size_t i = 0; i < frame->points.size(); ++i) {
      const Eigen::Vector3d p = lidar.pose * frame->points[i].xyz().cast<double>();
      const std::uint32_t id = frame->truth[i];
      double d = 0.0;
      if (id == kGroundId) {
        d = std::abs(p.z() - scene.ground.heightAt(p.x()));
      } else {
        const auto it = std::find_if(scene.objects.begin(), scene.objects.end(), [&](const auto& o) { return o.id == id; });
        ASSERT_NE(it, scene.objects.end()) << "truth " << id << " names no object";
        d = surfaceDistance(*it, scene.ground, 0.0, p);
      }
      ASSERT_LE(d, bound) << lidar.name << " point " << i << " labelled " << id;
      ++checked;
    }
  }
  EXPECT_GT(checked, 30000U);
}

TEST(SimScan, AFrameIsByteIdenticalWhateverTheThreadCountAndDiffersWithTheSeed) {
  Scene scene = randomScene(40, 2, 5);
  scene.lidars[0].dropout = 0.05;
  const auto r = raycaster(scene, 0.0);
  const auto one = r.scan(scene.lidars[0], 9, 3, 1);
  const auto four = r.scan(scene.lidars[0], 9, 3, 4);
  ASSERT_TRUE(one.ok() && four.ok());
  ASSERT_EQ(one->points.size(), four->points.size());
  EXPECT_EQ(std::memcmp(one->points.data(), four->points.data(), one->points.size() * sizeof(Point)), 0);
  EXPECT_EQ(one->truth, four->truth);
  EXPECT_EQ(one->rays, 32U * 2250U);
  // About 5 % of the returns dropped; another seed, other noise.
  const auto other = r.scan(scene.lidars[0], 10, 3, 1);
  EXPECT_NE(one->points, other->points);
  const auto no_dropout = [&] {
    LidarConfig l = scene.lidars[0];
    l.dropout = 0.0;
    return r.scan(l, 9, 3, 1);
  }();
  const double kept = static_cast<double>(one->points.size()) / static_cast<double>(no_dropout->points.size());
  EXPECT_NEAR(kept, 0.95, 0.01);
}

// The truth in use: every LiDAR of a random scene, its object points (in the scene frame) clustered
// as an edge clusters them, compared with the true objects point by point and object by object.
TEST(SimScan, ClusteringASimulatedFrameRecoversTheTrueObjects) {
  const Scene scene = randomScene(50, 3, 21);
  const auto r = raycaster(scene, 0.0);
  for (const LidarConfig& lidar : scene.lidars) {
    const auto frame = r.scan(lidar, scene.seed, 0);
    ASSERT_TRUE(frame.ok());
    Cloud objects;
    std::vector<std::int64_t> truth;
    const Cloud in_scene = transformCloud(frame->points, lidar.pose);
    for (std::size_t i = 0; i < in_scene.size(); ++i) {
      if (frame->truth[i] == kGroundId) continue;
      objects.push_back(in_scene[i]);
      truth.push_back(frame->truth[i]);
    }
    const Clustering clustering = euclideanClusters(objects, ClusteringParams{});
    const std::vector<std::int64_t> labels(clustering.labels.begin(), clustering.labels.end());
    const auto scores = randScores(truth, labels);
    const auto match = matchObjects(truth, labels);
    ASSERT_TRUE(scores.ok() && match.ok());
    std::printf("%s: %zu object points, ARI %.4f, %zu true objects: %zu whole, %zu split, %zu merged, %zu missed\n",
                lidar.name.c_str(), objects.size(), scores->adjusted_rand_index, match->objects_true, match->found_whole,
                match->split, match->merged, match->missed);
    // Objects stand at least 1 m apart, farther than eps: none is merged with another.
    EXPECT_GT(scores->adjusted_rand_index, 0.95) << lidar.name;
    EXPECT_EQ(match->merged, 0U) << lidar.name;
    // Within 12 m the HDL-32E's rings (1.33 degrees apart) are closer than eps (0.35 m), so every
    // object there is one cluster; farther away rings fall apart and thin objects drop below 10
    // points, which is the sensor, not the clustering.
    std::vector<std::int64_t> near_truth, near_labels;
    for (std::size_t i = 0; i < objects.size(); ++i) {
      const auto& o = *std::find_if(scene.objects.begin(), scene.objects.end(),
                                    [&](const SceneObject& so) { return so.id == truth[i]; });
      if ((o.xy - lidar.pose.translation().head<2>()).norm() > 12.0) continue;
      near_truth.push_back(truth[i]);
      near_labels.push_back(labels[i]);
    }
    const auto near = matchObjects(near_truth, near_labels);
    ASSERT_TRUE(near.ok());
    EXPECT_GT(near->objects_true, 0U) << lidar.name;
    EXPECT_EQ(near->found_whole, near->objects_true) << lidar.name;
  }
}

TEST(SimMotion, ObjectsFollowTheirVelocityAndWaypointsWithTheHeadingOfThePath) {
  SceneObject v = boxObject(1, {1, 2}, {1, 1, 1});
  v.motion.velocity_mps = {0, 2};
  EXPECT_TRUE(poseAt(v, 3.0).xy.isApprox(Eigen::Vector2d(1, 8)));
  EXPECT_NEAR(poseAt(v, 3.0).yaw_rad, M_PI / 2, 1e-12);
  SceneObject w = boxObject(2, {0, 0}, {1, 1, 1});
  w.motion.waypoints = {{0, 0}, {10, 0}, {10, 10}};
  w.motion.speed_mps = 2.0;
  EXPECT_TRUE(poseAt(w, 2.5).xy.isApprox(Eigen::Vector2d(5, 0)));
  EXPECT_NEAR(poseAt(w, 2.5).yaw_rad, 0.0, 1e-12);
  EXPECT_TRUE(poseAt(w, 7.5).xy.isApprox(Eigen::Vector2d(10, 5)));
  EXPECT_NEAR(poseAt(w, 7.5).yaw_rad, M_PI / 2, 1e-12);
  EXPECT_TRUE(poseAt(w, 100.0).xy.isApprox(Eigen::Vector2d(10, 10))) << "without loop it stops at the end";
  w.motion.loop = true;  // 10 + 10 + sqrt(200) around
  const double around = 20.0 + std::sqrt(200.0);
  EXPECT_TRUE(poseAt(w, around / 2.0 + 2.5).xy.isApprox(Eigen::Vector2d(5, 0), 1e-9));
  // A moving object is cast where it is at the scan's time.
  Scene s = sceneWith({v});
  const auto later = raycaster(s, 3.0).cast({1, 0, 0.5}, {0, 1, 0}, 100);
  ASSERT_TRUE(later.has_value());
  EXPECT_NEAR(later->distance_m, 7.5, kTol);
}

TEST(SimScene, RoundTripsThroughYamlAndNamesWhatIsWrong) {
  const Scene moving = movingScene(3, 2, 4, 2, 8);
  const auto parsed = parseScene(toYaml(moving));
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(toYaml(*parsed), toYaml(moving));
  EXPECT_EQ(parsed->objects.size(), 5U);
  EXPECT_EQ(parsed->cameras.size(), 2U);
  const auto error = [](const std::string& yaml) {
    const auto s = parseScene(yaml);
    return s.ok() ? std::string("accepted") : s.error().message;
  };
  const std::string lidar = "lidars: [{name: a, model: VLP-16}]\n";
  EXPECT_EQ(error(lidar + "objects: [{id: 1, parts: [{shape: cone}]}]"),
            "scene: objects[0].parts[0].shape: must be box or cylinder, got 'cone'");
  EXPECT_EQ(error(lidar + "objects: [{id: 1, parts: [{shape: box, size_m: [1, -1, 1]}]}]"),
            "scene: objects[0].parts[0].size_m: must be a positive number");
  EXPECT_EQ(error(lidar + "objects: [{id: 1, parts: [{shape: box, size_m: [1, 1, 1]}]}, {id: 1, parts: [{shape: cylinder, "
                          "radius_m: 1, height_m: 2}]}]"),
            "scene: objects[1].id: id 1 is used twice");
  EXPECT_EQ(error(lidar + "objects: [{id: 0, parts: [{shape: box, size_m: [1, 1, 1]}]}]"),
            "scene: objects[0].id: must be an integer from 1 (0 is the ground)");
  EXPECT_EQ(error("lidars: [{name: a, model: HDL-128}]"),
            "scene: lidars[0].model: no LiDAR model 'HDL-128' (known: VLP-16, HDL-32E, HDL-64E, OS1-64)");
  EXPECT_EQ(error(lidar + "colour: red"), "scene: colour: unknown key");
  EXPECT_EQ(error("objects: []"), "scene: lidars: a scene needs at least one LiDAR");
  EXPECT_EQ(error(lidar + "objects: [{id: 1, parts: [{shape: box, size_m: [1, 1, 1]}], motion: {waypoints: [[0, 0]], "
                          "speed_mps: 1}}]"),
            "scene: objects[0].motion.waypoints: needs at least 2 points");
}

TEST(SimScene, TheCommentedExampleLoadsAndItsCameraSeesTheArea) {
  const auto scene = loadScene(std::filesystem::path(FOGMAP_SOURCE_DIR) / "data" / "scenes" / "example.yaml");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->objects.size(), 4U);
  EXPECT_EQ(scene->lidars.size(), 2U);
  ASSERT_EQ(scene->cameras.size(), 1U);
  EXPECT_TRUE(scene->ground.step_x_m.has_value());
  const auto r = raycaster(*scene, 1.0);
  for (const LidarConfig& l : scene->lidars) {
    const auto frame = r.scan(l, scene->seed, 10);
    ASSERT_TRUE(frame.ok());
    EXPECT_EQ(std::set<std::uint32_t>(frame->truth.begin(), frame->truth.end()).size(), 5U) << l.name << " sees the ground and the 4 objects";
  }
  const CameraConfig& c = scene->cameras[0];
  const Eigen::Vector3d origin_in_camera = c.pose.inverse() * Eigen::Vector3d(0, 0, 0);
  EXPECT_GT(origin_in_camera.z(), 0.0) << "the camera looks at the area";
}

TEST(SimGenerators, RandomScenesHoldTheirObjectsApartAndTheLidarsFaceTheCentre) {
  const Scene a = randomScene(100, 7, 42);
  EXPECT_EQ(a.objects.size(), 100U);
  EXPECT_EQ(a.lidars.size(), 7U);
  EXPECT_EQ(toYaml(a), toYaml(randomScene(100, 7, 42))) << "same seed, same scene";
  EXPECT_NE(toYaml(a), toYaml(randomScene(100, 7, 43)));
  for (const LidarConfig& l : a.lidars) {
    const Eigen::Vector3d forward = l.pose.rotation() * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d to_centre = -l.pose.translation();
    if (to_centre.head<2>().norm() > 1.0) {
      EXPECT_GT(forward.head<2>().dot(to_centre.head<2>().normalized()), 0.99) << l.name;
    }
  }
  // Every pair of objects is apart: no ray of the scene can join two of them by contact.
  const auto r = raycaster(a);
  std::size_t seen = 0;
  for (const LidarConfig& l : a.lidars) {
    const auto frame = r.scan(l, 1, 0);
    std::set<std::uint32_t> ids(frame->truth.begin(), frame->truth.end());
    seen = std::max(seen, ids.size());
  }
  EXPECT_GT(seen, 40U) << "a LiDAR of the paper's placements sees many of the objects";

  const Scene moving = movingScene(4, 2, 4, 4, 3);
  for (const CameraConfig& c : moving.cameras) {
    // The area's centre projects near the middle of the image.
    const Eigen::Vector3d in_camera = c.pose.inverse() * Eigen::Vector3d(0, 0, 0.5);
    ASSERT_GT(in_camera.z(), 0.0) << c.name << " looks away";
    EXPECT_NEAR(c.fx * in_camera.x() / in_camera.z() + c.cx, c.cx, 1.0) << c.name;
    EXPECT_NEAR(c.fy * in_camera.y() / in_camera.z() + c.cy, c.cy, 1.0) << c.name;
  }
  const Scene factory = factoryScene(1);
  EXPECT_EQ(factory.lidars.size(), 5U);
  EXPECT_TRUE(parseScene(toYaml(factory)).ok());
}

// Parallel vehicle paths lie a lane (3 m) apart or more: seed 19 once put two cars 2.0 m apart side
// by side for the whole scene, 0.2 m between their bodies.
TEST(SimGenerators, MovingScenesKeepParallelVehiclesALaneApart) {
  int parallel_pairs = 0;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    const Scene scene = movingScene(6, 5, 4, 0, seed);
    std::vector<const SceneObject*> cars;
    for (const SceneObject& o : scene.objects) {
      if (o.label == "car") cars.push_back(&o);
    }
    ASSERT_EQ(cars.size(), 5u);
    for (std::size_t a = 0; a < cars.size(); ++a) {
      for (std::size_t b = a + 1; b < cars.size(); ++b) {
        const auto& wa = cars[a]->motion.waypoints;
        const auto& wb = cars[b]->motion.waypoints;
        for (const int axis : {0, 1}) {
          const bool parallel = wa.front()[axis] == wa.back()[axis] && wb.front()[axis] == wb.back()[axis];
          if (!parallel) continue;
          ++parallel_pairs;
          EXPECT_GE(std::abs(wa.front()[axis] - wb.front()[axis]), 3.0) << "seed " << seed << ": " << cars[a]->name << " and " << cars[b]->name;
        }
      }
    }
  }
  EXPECT_GT(parallel_pairs, 60);  // five cars: two or three on each axis in every scene
}

// Nothing passes through anything: seed 19 drove two cars through each other (0.4 m between their
// centres) and people through cars and through each other. Checked on a finer clock than the
// generator's (0.01 s against 0.02 s), with footprint() itself: no two bodies ever closer than
// 0.5 m (1 m for two vehicles) less what they move in 0.01 s (0.12 m at most, two cars at 6 m/s).
TEST(SimGenerators, MovingScenesNeverPassOneObjectThroughAnother) {
  int crossing_paths = 0;
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    const Scene scene = movingScene(6, 3, 4, 0, seed);
    ASSERT_EQ(scene.objects.size(), 9u);
    const auto ends = [](const SceneObject& o) { return std::pair(o.motion.waypoints[1], o.motion.waypoints[2]); };
    for (std::size_t a = 0; a < scene.objects.size(); ++a) {
      for (std::size_t b = a + 1; b < scene.objects.size(); ++b) {
        const auto [a0, a1] = ends(scene.objects[a]);
        const auto [b0, b1] = ends(scene.objects[b]);
        // Perpendicular paths across the area cross.
        if (std::abs((a1 - a0).normalized().dot((b1 - b0).normalized())) < 1e-9) ++crossing_paths;
      }
    }
    double least = std::numeric_limits<double>::infinity();
    for (int k = 0; k * 0.01 < scene.duration_s; ++k) {
      const double t = k * 0.01;
      std::vector<std::vector<Eigen::Vector2d>> outlines;
      for (const SceneObject& o : scene.objects) outlines.push_back(footprint(o, t));
      for (std::size_t a = 0; a < outlines.size(); ++a) {
        for (std::size_t b = a + 1; b < outlines.size(); ++b) {
          const bool vehicles = scene.objects[a].label == "car" && scene.objects[b].label == "car";
          const double gap = footprintGap(outlines[a], outlines[b]);
          least = std::min(least, gap - (vehicles ? 1.0 : 0.5));
          ASSERT_GE(gap, (vehicles ? 1.0 : 0.5) - 0.12)
              << "seed " << seed << " t " << t << " s: " << scene.objects[a].name << " and " << scene.objects[b].name;
        }
      }
    }
    std::printf("seed %2llu: least clearance beyond the rule %.3f m\n", static_cast<unsigned long long>(seed), least);
  }
  EXPECT_GT(crossing_paths, 12 * 10);  // paths do cross: the objects pass each other in time
}

// Scene time: scan n of a sensor at rate r shows fmod(n / r, duration_s), exactly also for scan
// numbers counted from the unix epoch.
TEST(SimSceneTime, WrapsAtTheSceneDurationWithTheAnalyticInstants) {
  Scene scene;
  EXPECT_DOUBLE_EQ(scene.duration_s, 60.0) << "the default duration";
  const std::vector<std::pair<std::uint64_t, double>> at_10hz = {
      {0, 0.0}, {1, 0.1}, {7, 0.7}, {599, 59.9}, {600, 0.0}, {601, 0.1}, {1234, 3.4}};
  for (const auto& [n, t] : at_10hz) {
    EXPECT_NEAR(sceneTime(scene, n, 10.0), t, 1e-12) << "scan " << n;
    EXPECT_NEAR(sceneTime(scene, n, 10.0), std::fmod(static_cast<double>(n) / 10.0, 60.0), 1e-9) << "scan " << n;
  }
  EXPECT_NEAR(sceneTime(scene, 601, 20.0), 30.05, 1e-12);
  EXPECT_NEAR(sceneTime(scene, 1201, 20.0), 0.05, 1e-12);
  EXPECT_NEAR(sceneTime(scene, 1199, 20.0), 59.95, 1e-12);
  EXPECT_NEAR(sceneTime(scene, 1200, 20.0), 0.0, 1e-12);
  scene.duration_s = 2.5;
  EXPECT_NEAR(sceneTime(scene, 24, 10.0), 2.4, 1e-12);
  EXPECT_NEAR(sceneTime(scene, 26, 10.0), 0.1, 1e-12);
}

TEST(SimSceneTime, LargeScanNumbersAreExactAtTwoRates) {
  Scene scene;  // 60 s
  // Scan numbers of 2024 at 10 and 20 Hz (periods since the unix epoch), and the largest one.
  for (const std::uint64_t n : {17'000'000'123ULL, 17'280'000'599ULL, 34'560'001'199ULL, ~0ULL}) {
    // 600 frames per cycle at 10 Hz, 1200 at 20 Hz: the remainder is an integer, the time exact.
    EXPECT_EQ(sceneTime(scene, n, 10.0), static_cast<double>(n % 600) / 10.0) << n;
    EXPECT_EQ(sceneTime(scene, n, 20.0), static_cast<double>(n % 1200) / 20.0) << n;
    EXPECT_GE(sceneTime(scene, n, 20.0), 0.0);
    EXPECT_LT(sceneTime(scene, n, 20.0), 60.0);
  }
  // n / 10 in double is only good to about 2e-7 s at n = 1.7e10; frames in a row stay a period apart.
  const std::uint64_t n = 17'000'000'123ULL;
  EXPECT_NEAR(sceneTime(scene, n + 1, 10.0) - sceneTime(scene, n, 10.0), 0.1, 1e-12);
  // Not a whole number of frames per cycle (1.25 s at 10 Hz is 12.5 frames): fmod(n / 10, 1.25)
  // is (4 n mod 50) / 40 exactly; long double keeps it within nanoseconds at these magnitudes.
  scene.duration_s = 1.25;
  for (const std::uint64_t m : {3ULL, 13ULL, 17'000'000'123ULL, 17'000'000'137ULL}) {
    EXPECT_NEAR(sceneTime(scene, m, 10.0), static_cast<double>((4 * m) % 50) / 40.0, 1e-8) << m;
  }
}

TEST(SimSceneTime, DurationIsReadCheckedAndWritten) {
  const std::string lidar = "lidars: [{name: a, model: VLP-16}]\n";
  const auto defaulted = parseScene(lidar);
  ASSERT_TRUE(defaulted.ok()) << defaulted.error().message;
  EXPECT_DOUBLE_EQ(defaulted->duration_s, 60.0);
  const auto given = parseScene(lidar + "duration_s: 12.5\n");
  ASSERT_TRUE(given.ok()) << given.error().message;
  EXPECT_DOUBLE_EQ(given->duration_s, 12.5);
  const auto again = parseScene(toYaml(*given));
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_DOUBLE_EQ(again->duration_s, 12.5);
  for (const char* bad : {"0", "-3", ".nan", ".inf", "long"}) {
    const auto parsed = parseScene(lidar + "duration_s: " + bad + "\n");
    ASSERT_FALSE(parsed.ok()) << bad;
    EXPECT_NE(parsed.error().message.find("scene: duration_s: "), std::string::npos) << parsed.error().message;
  }
}

}  // namespace
}  // namespace fogmap::sim
