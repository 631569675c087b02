// The simulated LiDAR as an edge's scans (services/edge_cluster/sim_scan_source.hpp): scan n is the
// ray caster's frame at the scene time of n, byte for byte; the LiDAR must exist and the topology's
// pose must be the scene's.
#include "services/edge_cluster/sim_scan_source.hpp"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/cloud_io.hpp"
#include "common/sim/generators.hpp"
#include "common/sim/raycaster.hpp"
#include "common/sim/scene.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;

// Scan numbers as edges compute them (periods since the unix epoch, 2024 at 10 Hz) and small ones.
const std::vector<std::uint64_t> kScanNumbers = {0, 7, 17'000'000'123ULL, 17'000'000'124ULL, 17'000'000'400ULL};

SensorConfig simSensor(const sim::Scene& scene, const std::string& lidar, const fs::path& file = "scene.yaml") {
  SensorConfig s;
  s.source = kSimSource;
  s.scene = file;
  s.lidar = lidar;
  s.rate_hz = 10.0;
  if (const sim::LidarConfig* l = scene.lidar(lidar)) s.pose = l->pose;
  return s;
}

// The oracle: the scene built at the scene time of scan n, LiDAR cast with the scene's seed for the
// scan's frame in the scene's cycle (n mod duration x rate).
Cloud castDirectly(const sim::Scene& scene, const std::string& lidar, std::uint64_t n, double rate_hz) {
  auto raycaster = sim::SceneRaycaster::build(scene, sim::sceneTime(scene, n, rate_hz));
  EXPECT_TRUE(raycaster.ok());
  if (!raycaster.ok()) return {};
  const auto cycle = static_cast<std::uint64_t>(std::llround(scene.duration_s * rate_hz));
  auto frame = raycaster->scan(*scene.lidar(lidar), scene.seed, n % cycle);
  EXPECT_TRUE(frame.ok());
  return frame.ok() ? frame->points : Cloud{};
}

bool byteIdentical(const Cloud& a, const Cloud& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Point)) == 0);
}

// A scene file in a fresh directory, removed at the end.
class SceneFile {
 public:
  explicit SceneFile(const sim::Scene& scene)
      : dir_(fs::temp_directory_path() / ("fogmap_sim_scan_" + std::to_string(std::random_device{}()))) {
    fs::create_directories(dir_);
    std::ofstream(path()) << sim::toYaml(scene);
  }
  ~SceneFile() {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  SceneFile(const SceneFile&) = delete;
  SceneFile& operator=(const SceneFile&) = delete;
  fs::path path() const { return dir_ / "scene.yaml"; }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

TEST(SimScanSource, ScanNIsTheRaycastersFrameAtTheSceneTimeOfNInAStaticScene) {
  const sim::Scene scene = sim::randomScene(12, 2, 3);
  auto source = SimScanSource::create(scene, simSensor(scene, "lidar-2"));
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_FALSE(source->moving());
  for (const std::uint64_t n : kScanNumbers) {
    const auto frame = source->at(n);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    EXPECT_EQ(frame->sequence, n);
    EXPECT_EQ(frame->file, fs::path("scene.yaml"));
    EXPECT_GT(frame->points.size(), 10000U);
    EXPECT_TRUE(byteIdentical(frame->points, castDirectly(scene, "lidar-2", n, 10.0))) << "scan " << n;
  }
  // Noise is drawn per frame: two scans of the still scene differ; one cycle later (600 scans at
  // 10 Hz for 60 s) a scan is the same again.
  EXPECT_FALSE(byteIdentical(source->at(7)->points, source->at(8)->points));
  EXPECT_TRUE(byteIdentical(source->at(7)->points, source->at(607)->points));
  EXPECT_EQ(source->emitted(), kScanNumbers.size() + 4);
}

TEST(SimScanSource, ScanNIsTheRaycastersFrameAtTheSceneTimeOfNInAMovingScene) {
  sim::Scene scene = sim::movingScene(4, 2, 2, 0, 5);
  scene.duration_s = 20.0;
  SensorConfig sensor = simSensor(scene, "lidar-1");
  sensor.rate_hz = 20.0;
  auto source = SimScanSource::create(scene, sensor);
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_TRUE(source->moving());
  for (const std::uint64_t n : kScanNumbers) {
    const auto frame = source->at(n);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    EXPECT_TRUE(byteIdentical(frame->points, castDirectly(scene, "lidar-1", n, 20.0))) << "scan " << n;
  }
  // The objects moved between the scene times of two scans: the truth of the frames differs where
  // noise alone could not make it (a noiseless LiDAR).
  scene.lidars[0].range_noise_m = 0.0;
  auto noiseless = SimScanSource::create(scene, sensor);
  ASSERT_TRUE(noiseless.ok());
  const std::uint64_t n = 17'000'000'123ULL;
  EXPECT_FALSE(byteIdentical(noiseless->at(n)->points, noiseless->at(n + 20)->points)) << "1 s later";
  // A whole scene duration (400 scans at 20 Hz) later the scene is where it was.
  EXPECT_TRUE(byteIdentical(noiseless->at(n)->points, noiseless->at(n + 400)->points));
}

TEST(SimScanSource, AnUnknownLidarIsNamedWithTheScenesLidars) {
  const sim::Scene scene = sim::randomScene(3, 3, 1);
  const SceneFile file(scene);
  SensorConfig sensor = simSensor(scene, "lidar-9", file.path());
  const auto source = SimScanSource::open(sensor);
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(source.error().message, file.path().string() +
                                        ": the scene has no LiDAR 'lidar-9' (its LiDARs: 'lidar-1', 'lidar-2', 'lidar-3')");
  sensor.scene = file.dir() / "missing.yaml";
  sensor.lidar = "lidar-1";
  const auto missing = SimScanSource::open(sensor);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("missing.yaml"), std::string::npos) << missing.error().message;
}

TEST(SimScanSource, IsDoneAfterItsFramesOrOnePassWithoutLooping) {
  sim::Scene scene = sim::randomScene(2, 1, 1);
  SensorConfig sensor = simSensor(scene, "lidar-1");
  sensor.frames = 3;
  auto limited = SimScanSource::create(scene, sensor);
  ASSERT_TRUE(limited.ok());
  for (std::uint64_t n = 100; n < 103; ++n) {
    EXPECT_FALSE(limited->done()) << n;
    EXPECT_TRUE(limited->at(n).ok());
  }
  EXPECT_TRUE(limited->done());
  EXPECT_FALSE(limited->at(103).ok()) << "at() after done() is an error, not a frame";

  // Without looping, one pass over the scene's time: 0.5 s at 10 Hz is 5 scans.
  scene.duration_s = 0.5;
  sensor.frames.reset();
  sensor.loop = false;
  auto once = SimScanSource::create(scene, sensor);
  ASSERT_TRUE(once.ok());
  int scans = 0;
  for (std::uint64_t n = 1000; !once->done() && scans < 100; ++n, ++scans) EXPECT_TRUE(once->at(n).ok());
  EXPECT_EQ(scans, 5);
  // Looping (the default) never ends.
  sensor.loop = true;
  auto endless = SimScanSource::create(scene, sensor);
  ASSERT_TRUE(endless.ok());
  for (std::uint64_t n = 0; n < 12; ++n) ASSERT_TRUE(endless->at(n).ok());
  EXPECT_FALSE(endless->done());
}

TEST(SimScanSource, TheTopologyPoseMustBeTheScenesLidarPose) {
  const sim::Scene scene = sim::randomScene(2, 2, 1);
  const sim::LidarConfig& lidar = scene.lidars[1];
  EXPECT_TRUE(checkLidarPose(lidar.pose, lidar).ok());
  Eigen::Isometry3d near = lidar.pose;
  near.translation().x() += 5e-7;
  EXPECT_TRUE(checkLidarPose(near, lidar).ok()) << "within the tolerance";

  Eigen::Isometry3d offset = lidar.pose;
  offset.translation().y() += 0.01;
  const Status moved = checkLidarPose(offset, lidar);
  ASSERT_FALSE(moved.ok());
  EXPECT_EQ(moved.error().code, ErrorCode::kInvalidArgument);
  const std::string& message = moved.error().message;
  EXPECT_NE(message.find("LiDAR 'lidar-2'"), std::string::npos) << message;
  EXPECT_NE(message.find("by 0.01 m"), std::string::npos) << message;
  // Both poses, as the topology writes them: y 25 in the scene, 25.01 in the topology.
  EXPECT_NE(message.find("translation_m: [25, 25.01, 1.8]"), std::string::npos) << message;
  EXPECT_NE(message.find("translation_m: [25, 25, 1.8]"), std::string::npos) << message;

  Eigen::Isometry3d turned = lidar.pose;
  turned.linear() = turned.linear() * Eigen::AngleAxisd(1e-4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_FALSE(checkLidarPose(turned, lidar).ok()) << "0.006 degrees of yaw";

  // As the edge runs it: from the sensor's scene file; recorded sensors have no scene to agree with.
  const SceneFile file(scene);
  SensorConfig sensor = simSensor(scene, "lidar-2", file.path());
  EXPECT_TRUE(checkSensorPose(sensor).ok());
  sensor.pose = offset;
  const Status refused = checkSensorPose(sensor);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().message.rfind(file.path().string() + ": the topology's pose", 0), 0U) << refused.error().message;
  SensorConfig recorded;
  recorded.source = file.dir();
  recorded.pose = offset;
  EXPECT_TRUE(checkSensorPose(recorded).ok());
}

TEST(SimScanSource, TheEdgesFactoryOpensSimulatedAndRecordedSensors) {
  const sim::Scene scene = sim::randomScene(5, 2, 2);
  const SceneFile file(scene);
  auto simulated = openScanProvider(simSensor(scene, "lidar-1", file.path()));
  ASSERT_TRUE(simulated.ok()) << simulated.error().message;
  const auto frame = (*simulated)->at(42);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  // The scene as read back from its file (toYaml keeps 10 digits) is what the edge casts.
  const auto loaded = sim::loadScene(file.path());
  ASSERT_TRUE(loaded.ok());
  EXPECT_TRUE(byteIdentical(frame->points, castDirectly(*loaded, "lidar-1", 42, 10.0)));
  EXPECT_NE((*simulated)->describe().find("'lidar-1'"), std::string::npos) << (*simulated)->describe();

  ASSERT_TRUE(writeKittiBin(file.dir() / "000.bin", Cloud{{1.0F, 2.0F, 3.0F, 0.0F}}).ok());
  SensorConfig recorded;
  recorded.source = file.dir();
  auto scans = openScanProvider(recorded);
  ASSERT_TRUE(scans.ok()) << scans.error().message;
  EXPECT_EQ((*scans)->describe(), "1 scan(s) from " + file.dir().string());
  const auto scan = (*scans)->at(0);
  ASSERT_TRUE(scan.ok());
  EXPECT_EQ(scan->points.size(), 1U);
  EXPECT_EQ((*scans)->emitted(), 1U);

  recorded.source = file.dir() / "nothing-here";
  EXPECT_FALSE(openScanProvider(recorded).ok());
}

}  // namespace
}  // namespace fogmap
