// Truth replay of camera detections against analytic answers: the image box of an object straight
// ahead, occlusion by a nearer object, clipping at the image's edge, and the seeded misses and
// jitter measured over many frames (binomial and sample-deviation bounds), byte-identical per seed.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <set>

#include "common/sim/camera_truth.hpp"
#include "common/sim/generators.hpp"
#include "common/sim/raycaster.hpp"
#include "tests/support/scene_raycaster.hpp"

namespace fogmap::sim {
namespace {

SceneObject crateObject(std::uint32_t id, Eigen::Vector2d xy, Eigen::Vector3d size) {
  SceneObject o;
  o.id = id;
  o.name = "crate-" + std::to_string(id);
  o.label = "crate";
  o.xy = xy;
  o.parts = {{Shape::kBox, Eigen::Vector3d::Zero(), size, 0.0}};
  return o;
}

SceneObject personObject(std::uint32_t id, Eigen::Vector2d xy, double radius, double height) {
  SceneObject o;
  o.id = id;
  o.name = "person-" + std::to_string(id);
  o.label = "person";
  o.xy = xy;
  o.parts = {{Shape::kCylinder, Eigen::Vector3d::Zero(), {2 * radius, 2 * radius, height}, 0.0}};
  return o;
}

// A camera 1 m up at the origin looking along +x: image x is -y, image y is -z.
CameraConfig forwardCamera() {
  CameraConfig c;
  c.name = "cam-a";
  c.pose = lookAt({0, 0, 1}, {10, 0, 1});
  c.fx = c.fy = 500.0;
  c.cx = 320.0;
  c.cy = 240.0;
  c.width = 640;
  c.height = 480;
  return c;
}

Scene cameraSceneWith(std::vector<SceneObject> objects) {
  Scene s;
  s.extent_m = 100.0;
  s.objects = std::move(objects);
  s.cameras = {forwardCamera()};
  return s;
}

using test_support::raycaster;

TruthDetectionFrame detect(const Scene& scene, const SceneRaycaster& r, std::uint64_t frame,
                           const TruthReplayConfig& config = {}) {
  auto f = truthDetections(scene, r, scene.cameras.front(), frame, config);
  EXPECT_TRUE(f.ok()) << (f.ok() ? "" : f.error().message);
  return f.ok() ? std::move(f).value() : TruthDetectionFrame{};
}

TEST(CameraTruth, PinholeOfInvertsTheCameraPose) {
  const CameraConfig c = forwardCamera();
  const camera::PinholeCamera p = pinholeOf(c);
  EXPECT_EQ(p.name, "cam-a");
  EXPECT_TRUE(p.distortion.none());
  EXPECT_TRUE(p.centre().isApprox(Eigen::Vector3d(0, 0, 1)));
  // On the optical axis: the principal point; 1 m to the left in the scene (+y) is left in the image.
  const auto axis = p.project({7, 0, 1});
  ASSERT_TRUE(axis.has_value());
  EXPECT_NEAR(axis->x(), 320.0, 1e-9);
  EXPECT_NEAR(axis->y(), 240.0, 1e-9);
  const auto left = p.project({10, 1, 1});
  ASSERT_TRUE(left.has_value());
  EXPECT_NEAR(left->x(), 320.0 - 50.0, 1e-9);
}

TEST(CameraTruth, BoxStraightAheadProjectsToItsAnalyticBox) {
  // A 2 m cube centred 10 m ahead: its near face (x = 9) spans y and z - 1 in [-1, 1], so the box
  // is the principal point -+ f / 9 both ways.
  const Scene scene = cameraSceneWith({crateObject(3, {10, 0}, {2, 2, 2})});
  const auto r = raycaster(scene, 2.5);
  const auto f = detect(scene, r, 0);
  ASSERT_EQ(f.detections.size(), 1U);
  const camera::Detection& d = f.detections[0];
  EXPECT_NEAR(d.box.left, 320.0 - 500.0 / 9.0, 1e-6);
  EXPECT_NEAR(d.box.right, 320.0 + 500.0 / 9.0, 1e-6);
  EXPECT_NEAR(d.box.top, 240.0 - 500.0 / 9.0, 1e-6);
  EXPECT_NEAR(d.box.bottom, 240.0 + 500.0 / 9.0, 1e-6);
  EXPECT_EQ(d.label, "crate");
  EXPECT_EQ(d.score, 1.0);
  EXPECT_EQ(d.camera, "cam-a");
  EXPECT_EQ(d.capture_time_ns, 2'500'000'000);
  EXPECT_EQ(f.capture_time_ns, 2'500'000'000);
  EXPECT_EQ(f.arrival_time_ns, 2'500'000'000);
  EXPECT_EQ(f.objects, std::vector<std::uint32_t>{3});
}

TEST(CameraTruth, PersonStraightAheadIsBoxedByItsSilhouette) {
  // A cylinder of radius r at distance d: the tangents from the camera give f r / sqrt(d^2 - r^2)
  // either side; top and bottom come from the near rim points at d - r.
  const double d = 8.0, radius = 0.3, height = 1.8;
  const Scene scene = cameraSceneWith({personObject(5, {d, 0}, radius, height)});
  const auto r = raycaster(scene);
  const auto f = detect(scene, r, 0);
  ASSERT_EQ(f.detections.size(), 1U);
  const camera::Box2d& b = f.detections[0].box;
  const double half = 500.0 * radius / std::sqrt(d * d - radius * radius);
  EXPECT_NEAR(b.left, 320.0 - half, 0.01 * half);  // the rims are 32-gons
  EXPECT_NEAR(b.right, 320.0 + half, 0.01 * half);
  EXPECT_NEAR(b.top, 240.0 - 500.0 * (height - 1.0) / (d - radius), 1e-6);
  EXPECT_NEAR(b.bottom, 240.0 + 500.0 * 1.0 / (d - radius), 1e-6);
  EXPECT_EQ(f.detections[0].label, "person");
}

TEST(CameraTruth, ObjectHiddenBehindAnotherIsNotDetected) {
  // A 1 m crate 20 m ahead lies wholly in the shadow of the 2 m cube at 10 m; moved 4 m aside, it is
  // seen. Both project into the image, so only occlusion can drop the hidden one.
  const Scene hidden = cameraSceneWith({crateObject(3, {10, 0}, {2, 2, 2}), crateObject(4, {20, 0}, {1, 1, 1})});
  const auto f = detect(hidden, raycaster(hidden), 0);
  EXPECT_EQ(f.objects, std::vector<std::uint32_t>{3});
  const Scene aside = cameraSceneWith({crateObject(3, {10, 0}, {2, 2, 2}), crateObject(4, {20, 4}, {1, 1, 1})});
  const auto g = detect(aside, raycaster(aside), 0);
  EXPECT_EQ(g.objects, (std::vector<std::uint32_t>{3, 4}));
  // Half hidden (its left half behind the cube's edge): still seen, through its free face centres.
  const Scene half = cameraSceneWith({crateObject(3, {10, 0}, {2, 2, 2}), crateObject(4, {20, -2.4}, {1, 1, 1})});
  EXPECT_EQ(detect(half, raycaster(half), 0).objects, (std::vector<std::uint32_t>{3, 4}));
}

TEST(CameraTruth, BoxesAreClippedToTheImageAndObjectsOutsideItOrBehindAreNot) {
  // 10 m ahead the image spans y in [-6.4, 6.4]: a cube at y = -6.4 (the right edge) is cut in half;
  // one at y = -10 is outside the field of view; one behind the camera is not in front of it.
  const Scene scene = cameraSceneWith({crateObject(3, {10, -6.4}, {2, 2, 2}), crateObject(4, {10, -10}, {2, 2, 2}),
                                       crateObject(5, {-10, 0}, {2, 2, 2})});
  const auto f = detect(scene, raycaster(scene), 0);
  ASSERT_EQ(f.objects, std::vector<std::uint32_t>{3});
  const camera::Box2d& b = f.detections[0].box;
  EXPECT_NEAR(b.left, 320.0 + 500.0 * 5.4 / 11.0, 1e-6);  // the far corner at y = -5.4 is the leftmost
  EXPECT_EQ(b.right, 640.0);
  EXPECT_GT(b.height(), 0.0);
}

// Twelve crates in a row, all in view and none hiding another.
Scene rowOfCrates() {
  std::vector<SceneObject> objects;
  for (std::uint32_t i = 0; i < 12; ++i) {
    objects.push_back(crateObject(i + 1, {15.0, -5.5 + static_cast<double>(i)}, {0.6, 0.6, 0.6}));
  }
  return cameraSceneWith(std::move(objects));
}

TEST(CameraTruth, MissRateDropsItsShareOfDetectionsAndIsByteIdenticalPerSeed) {
  const Scene scene = rowOfCrates();
  const auto r = raycaster(scene);
  ASSERT_EQ(detect(scene, r, 0).detections.size(), 12U);
  TruthReplayConfig config;
  config.miss_rate = 0.3;
  config.box_jitter_px = 1.5;
  config.latency_ms = 40.0;
  config.seed = 7;
  constexpr int kFrames = 500;
  std::size_t kept = 0;
  std::vector<TruthDetectionFrame> forward;
  for (int frame = 0; frame < kFrames; ++frame) {
    forward.push_back(detect(scene, r, static_cast<std::uint64_t>(frame), config));
    kept += forward.back().detections.size();
    EXPECT_EQ(forward.back().arrival_time_ns - forward.back().capture_time_ns, 40'000'000);
  }
  // Binomial(6000, 0.7): standard deviation 35.5; five of them either side.
  const double n = 12.0 * kFrames;
  const double sd = std::sqrt(n * 0.3 * 0.7);
  EXPECT_NEAR(static_cast<double>(kept), 0.7 * n, 5.0 * sd);

  // Asked again backwards: the same detections to the bit (the draws do not depend on call order).
  for (int frame = kFrames - 1; frame >= 0; --frame) {
    const auto again = detect(scene, r, static_cast<std::uint64_t>(frame), config);
    const auto& first = forward[static_cast<std::size_t>(frame)];
    ASSERT_EQ(again.objects, first.objects) << "frame " << frame;
    for (std::size_t k = 0; k < again.detections.size(); ++k) {
      const auto& a = again.detections[k].box;
      const auto& b = first.detections[k].box;
      EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "frame " << frame;
    }
  }

  // Another seed misses other detections; a higher miss rate misses a superset of them.
  TruthReplayConfig other = config;
  other.seed = 8;
  TruthReplayConfig more = config;
  more.miss_rate = 0.6;
  std::size_t differ = 0;
  for (int frame = 0; frame < kFrames; ++frame) {
    const auto& base = forward[static_cast<std::size_t>(frame)].objects;
    if (detect(scene, r, static_cast<std::uint64_t>(frame), other).objects != base) ++differ;
    const auto fewer = detect(scene, r, static_cast<std::uint64_t>(frame), more).objects;
    const std::set<std::uint32_t> kept_base(base.begin(), base.end());
    for (const auto id : fewer) EXPECT_TRUE(kept_base.count(id)) << "frame " << frame << " object " << id;
  }
  EXPECT_GT(differ, kFrames * 9 / 10);  // P(12 identical draws) = 0.3^12 + ... is tiny
}

TEST(CameraTruth, BoxJitterHasTheConfiguredSigmaOnEachEdge) {
  const Scene scene = rowOfCrates();
  const auto r = raycaster(scene);
  const auto exact = detect(scene, r, 0);
  ASSERT_EQ(exact.detections.size(), 12U);
  TruthReplayConfig config;
  config.box_jitter_px = 3.0;
  // Per edge: the mean and the root mean square of the offsets from the exact box.
  std::array<double, 4> sum{}, sum2{};
  constexpr int kFrames = 400;
  for (int frame = 0; frame < kFrames; ++frame) {
    const auto f = detect(scene, r, static_cast<std::uint64_t>(frame), config);
    ASSERT_EQ(f.detections.size(), 12U);
    for (std::size_t k = 0; k < 12; ++k) {
      const auto& a = f.detections[k].box;
      const auto& b = exact.detections[k].box;
      const std::array<double, 4> offsets = {a.left - b.left, a.top - b.top, a.right - b.right, a.bottom - b.bottom};
      for (std::size_t e = 0; e < 4; ++e) {
        sum[e] += offsets[e];
        sum2[e] += offsets[e] * offsets[e];
      }
    }
  }
  // 4800 draws per edge: the sample sigma is within 3 % of the true one at about three standard
  // errors (sigma / sqrt(2 n) = 1 %), the mean within 0.15 px (sigma / sqrt(n) = 0.043).
  const double n = 12.0 * kFrames;
  for (std::size_t e = 0; e < 4; ++e) {
    EXPECT_NEAR(sum[e] / n, 0.0, 0.15) << "edge " << e;
    EXPECT_NEAR(std::sqrt(sum2[e] / n), 3.0, 0.09) << "edge " << e;
  }
}

TEST(CameraTruth, InvalidConfigsAreRejected) {
  const Scene scene = rowOfCrates();
  const auto r = raycaster(scene);
  for (const TruthReplayConfig bad : {TruthReplayConfig{.miss_rate = 1.5}, TruthReplayConfig{.miss_rate = -0.1},
                                      TruthReplayConfig{.box_jitter_px = -1.0},
                                      TruthReplayConfig{.latency_ms = std::nan("")}}) {
    const auto f = truthDetections(scene, r, scene.cameras.front(), 0, bad);
    ASSERT_FALSE(f.ok());
    EXPECT_EQ(f.error().code, ErrorCode::kInvalidArgument);
  }
  CameraConfig no_focal = forwardCamera();
  no_focal.fx = 0.0;
  EXPECT_FALSE(truthDetections(scene, r, no_focal, 0, {}).ok());
}

}  // namespace
}  // namespace fogmap::sim
