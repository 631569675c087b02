// fogctl as a user runs it: the real binary in a child process, its stdout, stderr and exit code;
// a root aggregator stood in for by an in-process GlobalMapService on loopback where one is needed.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/camera/kitti.hpp"
#include "common/certs/certs.hpp"
#include "common/classify/object_classifier.hpp"
#include "common/config/camera_node.hpp"
#include "common/sim/generators.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/scene_topology.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/config/tracker_node.hpp"
#include "common/geometry/oriented_box.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/proto_convert.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/scratch_dir.hpp"
#include "harness/cluster_run.hpp"
#include "harness/compose.hpp"
#include "harness/launcher.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

fs::path fogctlBinary() { return harness::binaryDir() / "fogctl"; }

using test_support::readFile;
using test_support::ScratchDir;

struct Outcome {
  int code = -1;  // exit code; 128 + signal when killed; -1 when it had to be killed at the limit
  std::string out;
  std::string err;
};

// A child process with its stdout and stderr captured; every wait on it is bounded.
class Child {
 public:
  Child(const std::vector<std::string>& args, const fs::path& cwd) {
    int out[2];
    int err[2];
    if (::pipe2(out, O_CLOEXEC) != 0 || ::pipe2(err, O_CLOEXEC) != 0) return;
    // Everything the child touches is prepared before fork: it only calls async-signal-safe functions.
    std::vector<std::string> storage = args;
    std::vector<char*> argv;
    for (auto& a : storage) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string dir = cwd.string();
    pid_ = ::fork();
    if (pid_ == 0) {
      if (!dir.empty() && ::chdir(dir.c_str()) != 0) ::_exit(126);
      ::dup2(out[1], STDOUT_FILENO);
      ::dup2(err[1], STDERR_FILENO);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    ::close(out[1]);
    ::close(err[1]);
    out_fd_ = out[0];
    err_fd_ = err[0];
  }
  ~Child() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    closeFd(out_fd_);
    closeFd(err_fd_);
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  bool started() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }

  // Reads the output until `done(out, err)` holds, both streams close, or `limit` passes.
  bool readUntil(const std::function<bool(const std::string&, const std::string&)>& done,
                 std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (!done(out_, err_)) {
      if (out_fd_ < 0 && err_fd_ < 0) return false;
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return false;
      pollfd fds[2] = {{out_fd_, POLLIN, 0}, {err_fd_, POLLIN, 0}};
      if (::poll(fds, 2, static_cast<int>(left.count())) <= 0) continue;
      drain(fds[0], out_fd_, out_);
      drain(fds[1], err_fd_, err_);
    }
    return true;
  }

  // Waits for the child to exit (its streams close), killing it when `limit` passes first.
  Outcome finish(std::chrono::milliseconds limit = 60s) {
    readUntil([](const std::string&, const std::string&) { return false; }, limit);
    const bool timed_out = out_fd_ >= 0 || err_fd_ >= 0;
    if (timed_out) ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    reaped_ = true;
    Outcome o;
    o.out = out_;
    o.err = err_;
    if (timed_out) {
      o.code = -1;
    } else if (WIFEXITED(status)) {
      o.code = WEXITSTATUS(status);
    } else if (WIFSIGNALED(status)) {
      o.code = 128 + WTERMSIG(status);
    }
    return o;
  }

  const std::string& out() const { return out_; }
  const std::string& err() const { return err_; }

 private:
  static void closeFd(int& fd) {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
  static void drain(const pollfd& p, int& fd, std::string& into) {
    if (fd < 0 || (p.revents & (POLLIN | POLLHUP | POLLERR)) == 0) return;
    char buffer[4096];
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n > 0) {
      into.append(buffer, static_cast<std::size_t>(n));
    } else {
      closeFd(fd);
    }
  }

  pid_t pid_ = -1;
  bool reaped_ = false;
  int out_fd_ = -1;
  int err_fd_ = -1;
  std::string out_;
  std::string err_;
};

// Runs fogctl with `args` in `cwd` (the test's own when empty) and waits for it, bounded.
Outcome fogctl(const std::vector<std::string>& args, const fs::path& cwd = {}, std::chrono::milliseconds limit = 60s) {
  std::vector<std::string> argv{fogctlBinary().string()};
  argv.insert(argv.end(), args.begin(), args.end());
  Child child(argv, cwd);
  if (!child.started()) return {};
  return child.finish(limit);
}

std::string describe(const Outcome& o) { return "exit " + std::to_string(o.code) + "\nstdout:\n" + o.out + "\nstderr:\n" + o.err; }

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// KITTI .bin: float32 x, y, z, reflectance per point.
void writeKitti(const fs::path& file, const std::vector<std::array<float, 3>>& points) {
  std::ofstream out(file, std::ios::binary);
  for (const auto& p : points) {
    const float record[4] = {p[0], p[1], p[2], 0.5F};
    out.write(reinterpret_cast<const char*>(record), sizeof record);
  }
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) out.push_back(line);
  return out;
}

// ---------------------------------------------------------------------------------------------
// --help

// The commands `fogctl --help` lists (the first word of each indented line), and at least these.
std::set<std::string> listedCommands() {
  std::set<std::string> commands{"cluster", "bench", "demo", "up", "down", "watch", "geofence", "topology", "split"};
  for (const auto& line : lines(fogctl({"--help"}).out)) {
    if (line.rfind("  ", 0) != 0 || line.size() < 3 || line[2] == ' ') continue;
    commands.insert(line.substr(2, line.find(' ', 2) - 2));
  }
  return commands;
}

TEST(FogctlHelp, TopLevelHelpGoesToStdout) {
  const Outcome o = fogctl({"--help"});
  EXPECT_EQ(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(o.out, "usage: fogctl <command>")) << describe(o);
}

TEST(FogctlHelp, EveryCommandAnswersHelpWithItsUsageOnStdout) {
  for (const auto& command : listedCommands()) {
    const Outcome o = fogctl({command, "--help"});
    EXPECT_EQ(o.code, 0) << command << "\n" << describe(o);
    EXPECT_TRUE(contains(o.out, "usage: fogctl " + command)) << command << "\n" << describe(o);
    EXPECT_TRUE(o.err.empty()) << command << "\n" << describe(o);
  }
}

TEST(FogctlHelp, SubcommandsAndFlagsBeforeHelpStillGiveUsage) {
  for (const auto& args : {std::vector<std::string>{"bench", "clustering", "--help"},
                           std::vector<std::string>{"geofence", "set", "--help"},
                           std::vector<std::string>{"geofence", "query", "--help"},
                           std::vector<std::string>{"cluster", "--eps", "0.5", "--help"},
                           std::vector<std::string>{"split", "-h"},
                           std::vector<std::string>{"help", "watch"}}) {
    const Outcome o = fogctl(args);
    EXPECT_EQ(o.code, 0) << args[0] << " " << args[1] << "\n" << describe(o);
    EXPECT_TRUE(contains(o.out, "usage: fogctl " + (args[0] == "help" ? args[1] : args[0]))) << describe(o);
  }
}

// ---------------------------------------------------------------------------------------------
// watch, against a stand-in root

// A root aggregator's GlobalMapService: every subscriber gets `maps` global maps, then the stream
// stays open (without maps) until the server shuts down.
class FakeRoot final : public v1::GlobalMapService::Service {
 public:
  explicit FakeRoot(int maps) : maps_(maps) {
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(this);
    server_ = builder.BuildAndStart();
  }
  ~FakeRoot() override { shutdown(); }

  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  bool running() const { return server_ != nullptr && port_ > 0; }
  // Ends every open stream with an error, as a root that goes away does.
  void shutdown() {
    if (!server_) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    changed_.notify_all();
    server_->Shutdown(std::chrono::system_clock::now() + 1s);
    server_.reset();
  }

  grpc::Status Subscribe(grpc::ServerContext*, const v1::SubscribeRequest*,
                         grpc::ServerWriter<v1::GlobalMap>* writer) override {
    for (int k = 0; k < maps_; ++k) {
      GlobalMapMessage global;
      global.header.epoch = 100 + static_cast<std::uint64_t>(k);
      if (!writer->Write(toProto(global))) return grpc::Status::CANCELLED;
    }
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return stopping_; });
    return {grpc::StatusCode::UNAVAILABLE, "root going away"};
  }

 private:
  int maps_;
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool stopping_ = false;
};

TEST(FogctlWatch, SaysItCannotReachAMissingRootAndFails) {
  const auto ports = test_support::freePorts(1);
  ASSERT_EQ(ports.size(), 1U);
  const std::string target = "127.0.0.1:" + std::to_string(ports[0]);
  const Outcome o = fogctl({"watch", "--target", target}, {}, 30s);
  EXPECT_NE(o.code, 0) << describe(o);
  EXPECT_NE(o.code, -1) << "still running after 30 s\n" << describe(o);
  EXPECT_TRUE(contains(o.err, "cannot reach")) << describe(o);
  EXPECT_TRUE(contains(o.err, target)) << describe(o);
}

TEST(FogctlWatch, SaysTheRootWentAwayAndFails) {
  FakeRoot root(1);
  ASSERT_TRUE(root.running());
  Child watch({fogctlBinary().string(), "watch", "--target", root.target()}, {});
  ASSERT_TRUE(watch.started());
  ASSERT_TRUE(watch.readUntil([](const std::string& out, const std::string&) { return contains(out, "epoch 100"); }, 30s))
      << "stdout:\n" << watch.out() << "\nstderr:\n" << watch.err();
  root.shutdown();
  const Outcome o = watch.finish(30s);
  EXPECT_NE(o.code, 0) << describe(o);
  EXPECT_NE(o.code, -1) << "still running 30 s after the root went away\n" << describe(o);
  EXPECT_TRUE(contains(o.err, "lost the root")) << describe(o);
  EXPECT_TRUE(contains(o.err, root.target())) << describe(o);
}

TEST(FogctlWatch, SaysWhenNoGlobalMapComesAndGivesUpAfterTheTimeout) {
  FakeRoot root(0);
  ASSERT_TRUE(root.running());
  const Outcome o = fogctl({"watch", "--target", root.target(), "--idle-s", "0.2", "--timeout-s", "1"}, {}, 30s);
  EXPECT_NE(o.code, 0) << describe(o);
  EXPECT_NE(o.code, -1) << "still running after 30 s\n" << describe(o);
  EXPECT_TRUE(contains(o.err, "no global map from the root at " + root.target() + " for 0.2 s")) << describe(o);
  EXPECT_TRUE(contains(o.err, "giving up")) << describe(o);
}

TEST(FogctlWatch, EndsCleanlyAfterCountMaps) {
  FakeRoot root(3);
  ASSERT_TRUE(root.running());
  const Outcome o = fogctl({"watch", "--target", root.target(), "--count", "2"}, {}, 30s);
  EXPECT_EQ(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(o.out, "epoch 100")) << describe(o);
  EXPECT_TRUE(contains(o.out, "epoch 101")) << describe(o);
  EXPECT_FALSE(contains(o.out, "epoch 102")) << describe(o);
}

// ---------------------------------------------------------------------------------------------
// cluster

TEST(FogctlCluster, LabelsLineUpWithTheInputPointsNonFiniteOnesNoise) {
  ScratchDir dir("labels");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  // Two clusters along x (0.1 m apart, eps 0.35), an isolated point, and non-finite points between.
  writeKitti(dir.path() / "scan.bin", {{0.0F, 0.0F, 0.0F},
                                       {0.1F, 0.0F, 0.0F},
                                       {nan, 0.0F, 0.0F},
                                       {0.2F, 0.0F, 0.0F},
                                       {10.0F, 0.0F, 0.0F},
                                       {10.1F, nan, 0.0F},
                                       {10.1F, 0.0F, 0.0F},
                                       {10.2F, 0.0F, 0.0F},
                                       {50.0F, 0.0F, 0.0F},
                                       {inf, 1.0F, 1.0F},
                                       {0.3F, 0.0F, 0.0F}});
  const fs::path labels = dir.path() / "labels.txt";
  const Outcome o = fogctl({"cluster", "--input", (dir.path() / "scan.bin").string(), "--eps", "0.35", "--min-points", "3",
                            "--threads", "1", "--labels", labels.string()});
  ASSERT_EQ(o.code, 0) << describe(o);
  std::ifstream in(labels);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(lines(text.str()), (std::vector<std::string>{"0", "0", "-1", "0", "1", "-1", "1", "1", "-1", "-1", "0"}))
      << text.str();
}

TEST(FogctlCluster, ObjectsAreWrittenWithTheirOrientedBoxes) {
  ScratchDir dir("objects");
  // A car's two sides seen from the origin: 4 m along a 30 degree yaw and 1.6 m across it, from the
  // corner at (10, 5); and a post 20 m away. Points every 0.1 m, 5 rows 0.3 m apart.
  std::vector<std::array<float, 3>> points;
  const double c = std::cos(30.0 * M_PI / 180.0), s = std::sin(30.0 * M_PI / 180.0);
  for (int row = 0; row < 5; ++row) {
    const auto z = static_cast<float>(-1.2 + 0.3 * row);
    for (int k = 0; k <= 40; ++k) points.push_back({float(10.0 + 0.1 * k * c), float(5.0 + 0.1 * k * s), z});
    for (int k = 1; k <= 16; ++k) points.push_back({float(10.0 - 0.1 * k * s), float(5.0 + 0.1 * k * c), z});
    points.push_back({-20.0F, 0.0F, z});
    points.push_back({-20.0F, 0.05F, z + 0.3F});
  }
  writeKitti(dir.path() / "scan.bin", points);
  const fs::path objects = dir.path() / "objects.json";
  const fs::path model = fs::path(FOGMAP_SOURCE_DIR) / "data" / "models" / "lidar_classifier.yml.gz";
  const Outcome o = fogctl({"cluster", "--input", (dir.path() / "scan.bin").string(), "--min-points", "5", "--objects",
                            objects.string(), "--classifier", model.string()});
  ASSERT_EQ(o.code, 0) << describe(o);
  std::ifstream in(objects);
  const auto json = nlohmann::json::parse(in, nullptr, false);
  ASSERT_TRUE(json.is_array()) << "not a JSON array";
  ASSERT_EQ(json.size(), 2U) << json.dump();
  std::size_t total = 0;
  for (const auto& object : json) total += object.at("points").get<std::size_t>();
  EXPECT_EQ(total, points.size());
  const auto& car = json[0].at("points").get<int>() > 10 ? json[0] : json[1];
  const auto& box = car.at("box");
  EXPECT_NEAR(box.at("yaw").get<double>(), 30.0 * M_PI / 180.0, 1.0 * M_PI / 180.0) << car.dump();
  EXPECT_NEAR(box.at("length").get<double>(), 4.0, 0.05) << car.dump();
  EXPECT_NEAR(box.at("width").get<double>(), 1.6, 0.05) << car.dump();
  EXPECT_NEAR(box.at("height").get<double>(), 1.2, 1e-5) << car.dump();
  // The centre: the corner plus half of each side.
  EXPECT_NEAR(box.at("x").get<double>(), 10.0 + 2.0 * c - 0.8 * s, 0.05) << car.dump();
  EXPECT_NEAR(box.at("y").get<double>(), 5.0 + 2.0 * s + 0.8 * c, 0.05) << car.dump();
  // The origin lies behind the box (13.2 m along -length) and within its width (0.13 m right of
  // its axis): it sees the rear face.
  EXPECT_EQ(car.at("nearest").get<std::string>(), "rear") << car.dump();
  for (const auto& object : json) {
    EXPECT_TRUE(parseObjectClass(object.at("class").get<std::string>()).has_value()) << object.dump();
    EXPECT_GE(object.at("confidence").get<double>(), 0.0);
    EXPECT_LE(object.at("confidence").get<double>(), 1.0);
  }
  const Outcome missing = fogctl({"cluster", "--input", (dir.path() / "scan.bin").string(), "--objects", objects.string(),
                                  "--classifier", (dir.path() / "none.yml").string()});
  EXPECT_EQ(missing.code, 1) << describe(missing);
  EXPECT_TRUE(contains(missing.err, "none.yml")) << describe(missing);
}

// The real labelled KITTI car (000002, 34 m, 54 points), clustered as an edge with boxes does
// (ground removed, sensor-aware with the HDL-64E's beam table, vehicle parts joined): one object
// whose box lies on the label (no other object's box centre inside the label's box), classed car,
// whose vehicle box is within 0.5 m and 15 degrees of the label's. Without the join its bumper and
// its boot are two objects.
TEST(FogctlCluster, TheLabelledKittiCarIsOneObjectOfItsScan) {
  ScratchDir dir("cluster-kitti");
  const fs::path data = fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_object";
  const fs::path objects = dir.path() / "objects.json";
  const fs::path model = fs::path(FOGMAP_SOURCE_DIR) / "data" / "models" / "lidar_classifier.yml.gz";
  const Outcome o = fogctl({"cluster", "--input", (data / "velodyne" / "000002.bin").string(), "--remove-ground", "--lidar",
                            "HDL-64E", "--objects", objects.string(), "--classifier", model.string()});
  ASSERT_EQ(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(o.out, "sensor-aware, HDL-64E")) << describe(o);
  EXPECT_TRUE(contains(o.out, "vehicle parts joined")) << describe(o);
  const auto calibration = camera::parseKittiCalibration(test_support::readFile(data / "calib" / "000002.txt"));
  ASSERT_TRUE(calibration.ok()) << calibration.error().message;
  const auto labels = camera::parseKittiLabels(test_support::readFile(data / "label_2" / "000002.txt"));
  ASSERT_TRUE(labels.ok()) << labels.error().message;
  std::ifstream in(objects);
  const auto json = nlohmann::json::parse(in, nullptr, false);
  ASSERT_TRUE(json.is_array()) << "not a JSON array";
  int cars = 0;
  for (const auto& label : *labels) {
    if (label.type != "Car") continue;
    ++cars;
    const camera::VelodyneBox truth = camera::labelBoxInVelodyne(label, *calibration);
    std::vector<nlohmann::json> on_it;
    for (const auto& object : json) {
      const auto& box = object.at("box");
      const Eigen::Vector3d centre(box.at("x").get<double>(), box.at("y").get<double>(), box.at("z").get<double>());
      if (truth.contains(centre)) on_it.push_back(object);
    }
    ASSERT_EQ(on_it.size(), 1U) << "objects centred in the car's box: " << nlohmann::json(on_it).dump();
    const auto& car = on_it.front();
    EXPECT_EQ(car.at("class").get<std::string>(), "car") << car.dump();
    EXPECT_GE(car.at("points").get<int>(), 45) << car.dump();
    // The goal: the car's box within 0.5 m and 15 degrees of the label's.
    ASSERT_TRUE(car.contains("vehicle_box")) << car.dump();
    const auto& whole = car.at("vehicle_box");
    EXPECT_LT(std::hypot(whole.at("x").get<double>() - truth.centre.x(), whole.at("y").get<double>() - truth.centre.y()), 0.5)
        << car.dump();
    EXPECT_LT(axisAngleBetween(whole.at("yaw").get<double>(), truth.yaw), 15.0 * M_PI / 180.0) << car.dump();
  }
  EXPECT_EQ(cars, 1);
}

TEST(FogctlTrainClassifier, TrainsOnSomeSeedsScoresOthersAndWritesAModel) {
  ScratchDir dir("classifier");
  const fs::path model = dir.path() / "model.yml.gz";
  const Outcome o = fogctl({"train-classifier", "--train-seeds", "1-2", "--test-seeds", "5", "--objects", "20", "--lidars", "2",
                            "--trees", "10", "--out", model.string(), "--kitti", (fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_object").string()},
                           {}, 120s);
  ASSERT_EQ(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(o.out, "held-out seeds, confusion matrix")) << describe(o);
  EXPECT_TRUE(contains(o.out, "accuracy")) << describe(o);
  EXPECT_TRUE(contains(o.out, "000002 Car")) << describe(o);
  EXPECT_TRUE(fs::exists(model));
  const Outcome both = fogctl({"train-classifier", "--train-seeds", "1-3", "--test-seeds", "3,7", "--out", model.string()});
  EXPECT_EQ(both.code, 2) << describe(both);
  EXPECT_TRUE(contains(both.err, "seed 3 is in both")) << describe(both);
  const Outcome bad = fogctl({"train-classifier", "--train-seeds", "x-2"});
  EXPECT_EQ(bad.code, 2) << describe(bad);
  EXPECT_TRUE(contains(bad.err, "--train-seeds")) << describe(bad);
}

TEST(FogctlCluster, RefusesAnEpsOutsideTheAcceptedRangeNamingIt) {
  ScratchDir dir("eps");
  writeKitti(dir.path() / "scan.bin", {{0.0F, 0.0F, 0.0F}, {0.1F, 0.0F, 0.0F}});
  for (const std::string eps : {"1e-300", "0", "-1", "1000"}) {
    const Outcome o = fogctl({"cluster", "--input", (dir.path() / "scan.bin").string(), "--eps", eps});
    EXPECT_EQ(o.code, 2) << "--eps " << eps << "\n" << describe(o);
    EXPECT_TRUE(contains(o.err, "eps")) << describe(o);
    EXPECT_TRUE(contains(o.err, "between 0.001 and 100")) << describe(o);
  }
  const Outcome ok = fogctl({"cluster", "--input", (dir.path() / "scan.bin").string(), "--eps", "0.001", "--min-points", "1"});
  EXPECT_EQ(ok.code, 0) << describe(ok);
}

TEST(FogctlCluster, RefusesASparseScanAboveTheDefaultSizeBound) {
  ScratchDir dir("huge");
  const fs::path file = dir.path() / "huge.bin";
  { std::ofstream touch(file, std::ios::binary); }
  fs::resize_file(file, 300ULL << 20);  // sparse: no disk used, 300 MiB of zero points if read
  const Outcome o = fogctl({"cluster", "--input", file.string()}, {}, 30s);
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, "more than the scan size bound")) << describe(o);
  EXPECT_TRUE(contains(o.err, "--max-scan-bytes")) << describe(o);
}

TEST(FogctlCluster, MaxScanBytesBoundsTheInput) {
  ScratchDir dir("bound");
  const fs::path file = dir.path() / "scan.bin";
  writeKitti(file, {{0.0F, 0.0F, 0.0F}, {0.1F, 0.0F, 0.0F}, {0.2F, 0.0F, 0.0F}});  // 48 bytes
  const Outcome refused = fogctl({"cluster", "--input", file.string(), "--max-scan-bytes", "47"});
  EXPECT_EQ(refused.code, 2) << describe(refused);
  EXPECT_TRUE(contains(refused.err, "more than the scan size bound of 47 bytes")) << describe(refused);
  const Outcome accepted = fogctl({"cluster", "--input", file.string(), "--max-scan-bytes", "48", "--min-points", "1"});
  EXPECT_EQ(accepted.code, 0) << describe(accepted);
  for (const std::string bad : {"0", "-5", "lots"}) {
    const Outcome o = fogctl({"cluster", "--input", file.string(), "--max-scan-bytes", bad});
    EXPECT_EQ(o.code, 2) << bad << "\n" << describe(o);
    EXPECT_TRUE(contains(o.err, "--max-scan-bytes")) << describe(o);
  }
}

// ---------------------------------------------------------------------------------------------
// up / down

bool processGone(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  if (!stat) return true;
  std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
  const auto paren = text.rfind(')');
  return paren != std::string::npos && paren + 2 < text.size() && text[paren + 2] == 'Z';
}

std::string cmdline(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/cmdline");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (auto& c : text) {
    if (c == '\0') c = ' ';
  }
  return text;
}

// The pids recorded in every `pids` file under `root`.
std::vector<pid_t> recordedPids(const fs::path& root) {
  std::vector<pid_t> out;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().filename() != "pids") continue;
    std::ifstream in(it->path());
    pid_t pid = 0;
    std::string rest;
    while (in >> pid && std::getline(in, rest)) out.push_back(pid);
  }
  return out;
}

// Whatever happens in a test, the services it started do not outlive it: they are killed by pid
// when their command line still names the test's topology file.
class ServiceReaper {
 public:
  explicit ServiceReaper(fs::path topology) : topology_(std::move(topology)) {}
  ~ServiceReaper() {
    for (const pid_t pid : pids_) {
      if (contains(cmdline(pid), topology_.string())) ::kill(pid, SIGKILL);
    }
  }
  void track(const std::vector<pid_t>& pids) { pids_.insert(pids_.end(), pids.begin(), pids.end()); }

 private:
  fs::path topology_;
  std::vector<pid_t> pids_;
};

// A one-edge star on free ports, written to dir/name.yaml; the edge replays the bundled scans
// forever, so both services run until stopped. With `tls`, its tls section is that.
fs::path writeTopology(const fs::path& dir, const std::string& name, const std::optional<TlsConfig>& tls = std::nullopt) {
  const auto ports = test_support::freePorts(3);
  if (ports.size() != 3) return {};
  TopologyConfig t = makeStarTopology(1, fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a", 40000);
  t.name = name;
  for (auto& n : t.nodes) {
    if (n.role == Role::kAggregator) {
      n.port = ports[0];
      n.metrics_port = ports[1];
    } else {
      n.metrics_port = ports[2];
      n.sensor->frames.reset();
      n.sensor->loop = true;
    }
  }
  t.tls = tls;
  const fs::path file = dir / (name + ".yaml");
  std::ofstream(file) << toYaml(t);
  return file;
}

// Splits a printed shell command on spaces, honouring single quotes.
std::vector<std::string> shellWords(const std::string& command) {
  std::vector<std::string> words;
  std::string word;
  bool quoted = false;
  bool any = false;
  for (const char c : command) {
    if (c == '\'') {
      quoted = !quoted;
      any = true;
    } else if (c == ' ' && !quoted) {
      if (any) words.push_back(word);
      word.clear();
      any = false;
    } else {
      word += c;
      any = true;
    }
  }
  if (any) words.push_back(word);
  return words;
}

TEST(FogctlUp, DetachedHintStopsTheClusterFromAnotherDirectory) {
  ScratchDir dir("hint");
  const fs::path here = dir.path() / "here";
  const fs::path elsewhere = dir.path() / "elsewhere";
  fs::create_directories(here);
  fs::create_directories(elsewhere);
  const fs::path topology = writeTopology(dir.path(), "hint-star");
  ASSERT_FALSE(topology.empty());
  ServiceReaper reaper(topology);

  const Outcome up = fogctl({"up", topology.string(), "--detach", "--state", "run state"}, here, 90s);
  reaper.track(recordedPids(dir.path()));
  ASSERT_EQ(up.code, 0) << describe(up);
  const std::vector<pid_t> pids = recordedPids(here / "run state");
  ASSERT_EQ(pids.size(), 2U) << describe(up);

  std::string hint;
  for (const auto& line : lines(up.out)) {
    if (line.rfind("stop it with: ", 0) == 0) hint = line.substr(std::strlen("stop it with: "));
  }
  const fs::path state = fs::canonical(here / "run state");
  EXPECT_EQ(hint, "fogctl down --state '" + state.string() + "'") << describe(up);
  const auto words = shellWords(hint);
  ASSERT_GE(words.size(), 2U);
  ASSERT_EQ(words[0], "fogctl");

  const Outcome down = fogctl(std::vector<std::string>(words.begin() + 1, words.end()), elsewhere, 60s);
  EXPECT_EQ(down.code, 0) << describe(down);
  for (const pid_t pid : pids) EXPECT_TRUE(processGone(pid)) << "pid " << pid << " still runs\n" << describe(down);
}

TEST(FogctlUp, DefaultStateIsFoundByDownFromAnotherDirectory) {
  ScratchDir dir("default-state");
  const fs::path here = dir.path() / "here";
  const fs::path elsewhere = dir.path() / "elsewhere";
  fs::create_directories(here);
  fs::create_directories(elsewhere);
  const fs::path topology = writeTopology(here, "default-star");
  ASSERT_FALSE(topology.empty());
  ServiceReaper reaper(topology);

  const Outcome up = fogctl({"up", "default-star.yaml", "--detach"}, here, 90s);
  const std::vector<pid_t> pids = recordedPids(dir.path());
  reaper.track(pids);
  ASSERT_EQ(up.code, 0) << describe(up);
  ASSERT_EQ(pids.size(), 2U) << describe(up);

  const Outcome down = fogctl({"down", fs::relative(topology, elsewhere).string()}, elsewhere, 60s);
  EXPECT_EQ(down.code, 0) << describe(down);
  for (const pid_t pid : pids) EXPECT_TRUE(processGone(pid)) << "pid " << pid << " still runs\n" << describe(down);
}

TEST(FogctlDown, LeavesAloneARecordedPidThatIsNoLongerAService) {
  ScratchDir dir("stale");
  // An unrelated live process whose pid a stale record names: the state of a cluster that ended
  // long ago, its pids since reused.
  Child bystander({"/bin/sleep", "120"}, {});
  ASSERT_TRUE(bystander.started());
  const pid_t pid = bystander.pid();
  const fs::path state = dir.path() / "state";
  fs::create_directories(state);
  {
    // Without a start time (an older fogctl's record), and with a start time that is not the process's.
    std::ofstream pids(state / "pids");
    pids << pid << " edge-1\n" << pid << " sink 12345\n";
  }
  const Outcome down = fogctl({"down", "--state", state.string()}, dir.path(), 60s);
  EXPECT_FALSE(processGone(pid)) << "fogctl down killed an unrelated process\n" << describe(down);
  EXPECT_TRUE(contains(down.err, "pid " + std::to_string(pid) + " (edge-1)")) << describe(down);
  EXPECT_TRUE(contains(down.err, "pid " + std::to_string(pid) + " (sink)")) << describe(down);
  EXPECT_TRUE(contains(down.err, "left alone")) << describe(down);
}

// ---------------------------------------------------------------------------------------------
// certs, and the clients' identities with TLS

bool ownerOnly(const fs::path& file) {
  return (fs::status(file).permissions() & fs::perms::all) == (fs::perms::owner_read | fs::perms::owner_write);
}

TEST(FogctlCerts, WritesACaAndACertificatePerNodeAndClientKeysReadableByTheirOwnerOnly) {
  ScratchDir dir("certs");
  const fs::path topology = writeTopology(dir.path(), "certs-star");
  ASSERT_FALSE(topology.empty());
  const fs::path out = dir.path() / "pki";
  const Outcome made = fogctl({"certs", topology.string(), "--out", out.string(), "--days", "2", "--clients", "operator,ci"});
  ASSERT_EQ(made.code, 0) << describe(made);
  EXPECT_TRUE(contains(made.out, "tls: {ca: pki/ca.crt")) << describe(made);
  const std::string ca = readFile(out / "ca.crt");
  const auto now = std::chrono::system_clock::now();
  for (const std::string name : {"sink", "edge-1", "operator", "ci"}) {
    SCOPED_TRACE(name);
    EXPECT_TRUE(ownerOnly(out / (name + ".key")));
    const std::string cert = readFile(out / (name + ".crt"));
    const Status verified = verifyCertificate(cert, ca, now);
    EXPECT_TRUE(verified.ok()) << verified.error().message;
    EXPECT_FALSE(verifyCertificate(cert, ca, now + std::chrono::hours(24 * 3)).ok()) << "valid beyond --days";
    EXPECT_EQ(certificateCommonName(cert).value(), name);
    const auto loaded = loadTls(TlsIdentity{out / "ca.crt", out / (name + ".crt"), out / (name + ".key")}, now);
    EXPECT_TRUE(loaded.ok()) << loaded.error().message;
  }
  EXPECT_TRUE(ownerOnly(out / "ca.key"));

  // The CA is not replaced by accident: what it issued would stop being trusted.
  const Outcome again = fogctl({"certs", topology.string(), "--out", out.string()});
  EXPECT_EQ(again.code, 2) << describe(again);
  EXPECT_TRUE(contains(again.err, "--force")) << describe(again);
  EXPECT_EQ(readFile(out / "ca.crt"), ca);
  const Outcome forced = fogctl({"certs", topology.string(), "--out", out.string(), "--force"});
  EXPECT_EQ(forced.code, 0) << describe(forced);
  EXPECT_NE(readFile(out / "ca.crt"), ca);

  for (const auto& bad : {std::vector<std::string>{"--clients", "../x"}, {"--clients", "sink"},
                         {"--days", "0"}}) {
    std::vector<std::string> args{"certs", topology.string(), "--out", (dir.path() / "other").string()};
    args.insert(args.end(), bad.begin(), bad.end());
    const Outcome o = fogctl(args);
    EXPECT_EQ(o.code, 2) << bad[0] << " " << bad[1] << "\n" << describe(o);
  }
}

TEST(FogctlTls, ClientsWithoutAnIdentityAreToldHowToGiveOne) {
  ScratchDir dir("identity");
  const fs::path topology = writeTopology(dir.path(), "tls-star", TlsConfig{"pki/ca.crt", "pki", {"operator"}});
  ASSERT_FALSE(topology.empty());
  ASSERT_EQ(fogctl({"certs", topology.string(), "--out", (dir.path() / "pki").string(), "--clients", "ops"}).code, 0);
  // No operator certificate: the default identity is missing, and fogctl says what to give.
  Outcome o = fogctl({"watch", topology.string()}, {}, 30s);
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, "--identity NAME")) << describe(o);
  EXPECT_TRUE(contains(o.err, "operator.crt")) << describe(o);
  o = fogctl({"geofence", "query", topology.string(), "--identity", "nobody"}, {}, 30s);
  EXPECT_NE(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(o.err, "nobody.crt")) << describe(o);
  o = fogctl({"geofence", "query", "--target", "127.0.0.1:1", "--identity", "ops"}, {}, 30s);
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, "--identity needs the topology file")) << describe(o);
  o = fogctl({"watch", "--target", "127.0.0.1:1", "--cert", (dir.path() / "pki" / "ops.crt").string()}, {}, 30s);
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, "--key is missing")) << describe(o);
}

TEST(FogctlTls, UpWatchAndGeofenceOverMutualTls) {
  ScratchDir dir("tls-up");
  const fs::path topology = writeTopology(dir.path(), "tls-up-star", TlsConfig{"pki/ca.crt", "pki", {"operator"}});
  ASSERT_FALSE(topology.empty());
  const fs::path pki = dir.path() / "pki";
  const Outcome certs = fogctl({"certs", topology.string(), "--out", pki.string()});
  ASSERT_EQ(certs.code, 0) << describe(certs);
  ServiceReaper reaper(topology);
  const Outcome up = fogctl({"up", topology.string(), "--detach", "--state", (dir.path() / "state").string()}, {}, 90s);
  reaper.track(recordedPids(dir.path()));
  ASSERT_EQ(up.code, 0) << describe(up);
  const auto loaded = loadTopology(topology);
  ASSERT_TRUE(loaded.ok());
  const std::string target = loaded->root()->host + ":" + std::to_string(loaded->root()->port);

  Outcome o = fogctl({"watch", topology.string(), "--count", "1"}, {}, 60s);  // as operator, by default
  EXPECT_EQ(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(o.out, "epoch ")) << describe(o);
  o = fogctl({"watch", "--target", target, "--count", "1", "--cert", (pki / "edge-1.crt").string(), "--key",
              (pki / "edge-1.key").string(), "--ca", (pki / "ca.crt").string()},
             {}, 60s);
  EXPECT_EQ(o.code, 0) << describe(o);
  o = fogctl({"watch", "--target", target, "--count", "1"}, {}, 60s);  // plaintext
  EXPECT_EQ(o.code, 1) << describe(o);
  EXPECT_TRUE(contains(o.err, "cannot reach the root")) << describe(o);

  o = fogctl({"geofence", "set", topology.string(), "--name", "front", "--box", "0,-4,-3,20,4,3"}, {}, 60s);
  EXPECT_EQ(o.code, 0) << describe(o);
  o = fogctl({"geofence", "set", topology.string(), "--identity", "edge-1", "--name", "x", "--box", "0,0,0,1,1,1"}, {}, 60s);
  EXPECT_EQ(o.code, 1) << describe(o);
  EXPECT_TRUE(contains(o.err, "'edge-1' may not set geofences")) << describe(o);
  o = fogctl({"geofence", "query", topology.string(), "--identity", "edge-1"}, {}, 60s);
  EXPECT_EQ(o.code, 0) << describe(o);

  const Outcome down = fogctl({"down", "--state", (dir.path() / "state").string()}, {}, 60s);
  EXPECT_EQ(down.code, 0) << describe(down);
}

// The services themselves check their TLS files when they start: a missing or wrong one stops the
// service at once, exit code 2, naming the file.
TEST(ServicesTls, AMissingOrWrongCertificateStopsAServiceAtStartNamingTheFile) {
  ScratchDir dir("tls-start");
  const fs::path topology = writeTopology(dir.path(), "tls-start-star", TlsConfig{"pki/ca.crt", "pki", {}});
  ASSERT_FALSE(topology.empty());
  const fs::path pki = dir.path() / "pki";
  ASSERT_EQ(fogctl({"certs", topology.string(), "--out", pki.string()}).code, 0);
  const auto service = [&](const std::string& binary, const std::string& node) {
    Child child({(harness::binaryDir() / binary).string(), "--topology", topology.string(), "--node", node}, {});
    return child.finish(30s);
  };
  // The edge's certificate and key replaced by the sink's: the right CA, the wrong name.
  fs::copy_file(pki / "sink.crt", pki / "edge-1.crt", fs::copy_options::overwrite_existing);
  fs::copy_file(pki / "sink.key", pki / "edge-1.key", fs::copy_options::overwrite_existing);
  Outcome o = service("edge-cluster", "edge-1");
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, (pki / "edge-1.crt").string())) << describe(o);
  EXPECT_TRUE(contains(o.err, "issued to 'sink', not to 'edge-1'")) << describe(o);
  fs::remove(pki / "sink.key");
  o = service("merge-aggregator", "sink");
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, (pki / "sink.key").string())) << describe(o);
  fs::remove(pki / "ca.crt");
  o = service("edge-cluster", "edge-1");
  EXPECT_EQ(o.code, 2) << describe(o);
  EXPECT_TRUE(contains(o.err, (pki / "ca.crt").string())) << describe(o);
}

// True when a TCP connection to address:port is accepted.
bool accepts(const std::string& address, std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  const bool ok = ::inet_pton(AF_INET, address.c_str(), &to.sin_addr) == 1 &&
                  ::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) == 0;
  ::close(fd);
  return ok;
}

// A service listens on the address its node has in the topology, not on every interface: an
// aggregator on 127.0.0.2 cannot be reached on 127.0.0.1, neither its gRPC port nor /metrics.
TEST(ServicesListen, OnTheTopologysAddressOnly) {
  ScratchDir dir("listen");
  const fs::path topology = writeTopology(dir.path(), "listen-star");
  ASSERT_FALSE(topology.empty());
  auto t = loadTopology(topology);
  ASSERT_TRUE(t.ok()) << t.error().message;
  for (auto& n : t->nodes) n.host = "127.0.0.2";
  std::ofstream(topology) << toYaml(*t);
  const NodeConfig& sink = *t->root();
  Child aggregator({(harness::binaryDir() / "merge-aggregator").string(), "--topology", topology.string(), "--node", "sink"}, {});
  ASSERT_TRUE(aggregator.started());
  ASSERT_TRUE(aggregator.readUntil([](const std::string&, const std::string& err) { return contains(err, "ready"); }, 30s))
      << aggregator.err();
  EXPECT_TRUE(accepts("127.0.0.2", sink.port));
  EXPECT_TRUE(accepts("127.0.0.2", sink.metrics_port));
  EXPECT_FALSE(accepts("127.0.0.1", sink.port));
  EXPECT_FALSE(accepts("127.0.0.1", sink.metrics_port));
}

// ---------------------------------------------------------------------------------------------
// topology --scene: a cluster of simulated LiDARs

// A random scene of 3 LiDARs through the commands a user types (fogctl scene, fogctl topology
// --scene), then the topology run as real processes on loopback: every edge simulates its LiDAR at
// the scene's pose and the root publishes epochs to which all three contributed.
TEST(FogctlTopologyScene, ARandomScenesTopologyRunsAsAClusterOfSimulatedLidars) {
  ScratchDir dir("scene");
  const Outcome scene_made = fogctl({"scene", "random", "--objects", "30", "--lidars", "3", "--seed", "4", "--out", "s.yaml"},
                                    dir.path());
  ASSERT_EQ(scene_made.code, 0) << describe(scene_made);
  fs::create_directories(dir.path() / "topologies");
  const Outcome written =
      fogctl({"topology", "--scene", "s.yaml", "--frames", "20", "--out", "topologies/sim.yaml"}, dir.path());
  ASSERT_EQ(written.code, 0) << describe(written);
  EXPECT_TRUE(contains(readFile(dir.path() / "topologies" / "sim.yaml"), "scene: ../s.yaml"))
      << "the scene is named relative to the topology file";

  const auto scene = sim::loadScene(dir.path() / "s.yaml");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  ASSERT_EQ(scene->lidars.size(), 3U);
  auto topology = loadTopology(dir.path() / "topologies" / "sim.yaml");
  ASSERT_TRUE(topology.ok()) << topology.error().message;
  std::vector<const NodeConfig*> edges;
  for (const NodeConfig& n : topology->nodes) {
    if (n.role == Role::kEdge) edges.push_back(&n);
  }
  ASSERT_EQ(edges.size(), 3U);
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const sim::LidarConfig& lidar = scene->lidars[i];
    SCOPED_TRACE(lidar.name);
    EXPECT_EQ(edges[i]->name, "edge-" + lidar.name);
    EXPECT_EQ(edges[i]->id, i + 1);
    ASSERT_TRUE(edges[i]->sensor && edges[i]->sensor->simulated());
    EXPECT_EQ(edges[i]->sensor->lidar, lidar.name);
    EXPECT_EQ(fs::weakly_canonical(edges[i]->sensor->scene), fs::weakly_canonical(dir.path() / "s.yaml"));
    EXPECT_LT((edges[i]->sensor->pose.translation() - lidar.pose.translation()).norm(), 1e-9);
    EXPECT_LT((edges[i]->sensor->pose.linear() - lidar.pose.linear()).cwiseAbs().maxCoeff(), 1e-9);
  }

  test_support::useFreePorts(*topology);
  topology->deadline_ms = 500.0;  // a loaded 2-core machine must not turn slow epochs into partial ones
  harness::RunOptions options;
  options.frames = 1000;  // everything the edges produce (20 scans each)
  options.timeout = 25s;
  fs::create_directories(dir.path() / "run");
  const auto run = harness::runCluster(dir.path() / "run", *topology, options);
  ASSERT_TRUE(run.ok()) << run.error().message;
  std::size_t complete = 0;
  for (const auto& [epoch, global] : run->epochs) {
    if (!global.header.missing_nodes.empty() || !global.header.failed_nodes.empty()) continue;
    ++complete;
    EXPECT_EQ(global.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2, 3})) << "epoch " << epoch;
    EXPECT_GE(global.map.objects.size(), 10U) << "epoch " << epoch << ": the scene's 30 objects, seen from three sides";
  }
  EXPECT_GE(complete, 5U) << run->epochs.size() << " epochs published";
}

// --scene-start scores a fixed stretch of the scene: the warm-up before it and the scored lists
// after it must fit in the 60 s cycle (30 lists = 3 s before, --track-frames after at 10 Hz), and it
// needs a scene with moving objects and cameras. Refused before anything starts.
TEST(FogctlDemoScene, SceneStartLeavesRoomForTheWarmUpAndTheScoredLists) {
  ScratchDir dir("scene-start");
  const Outcome made = fogctl(
      {"scene", "moving", "--people", "2", "--vehicles", "1", "--lidars", "1", "--cameras", "1", "--out", "s.yaml"}, dir.path());
  ASSERT_EQ(made.code, 0) << describe(made);
  const auto refused = [&](std::vector<std::string> flags, const std::string& why) {
    std::vector<std::string> command = {"demo", "--scene", "s.yaml"};
    command.insert(command.end(), flags.begin(), flags.end());
    const Outcome o = fogctl(command, dir.path());
    EXPECT_EQ(o.code, 2) << describe(o);  // a usage error
    EXPECT_TRUE(contains(o.err, why)) << describe(o);
  };
  refused({"--scene-start", "2.9"}, "--scene-start must be a scene time in [3, 50] s");
  refused({"--scene-start", "50.1"}, "in [3, 50] s");
  refused({"--scene-start", "30", "--track-frames", "400"}, "in [3, 20] s");
  refused({"--scene-start", "soon"}, "--scene-start");
  const Outcome still =
      fogctl({"scene", "moving", "--people", "2", "--vehicles", "0", "--lidars", "1", "--cameras", "0", "--out", "still.yaml"},
             dir.path());
  ASSERT_EQ(still.code, 0) << describe(still);
  const Outcome o = fogctl({"demo", "--scene", "still.yaml", "--scene-start", "10"}, dir.path());
  EXPECT_EQ(o.code, 2) << describe(o);  // a usage error
  EXPECT_TRUE(contains(o.err, "need a scene with moving objects and cameras")) << describe(o);
}

// A scene's edges cluster sensor-aware with their LiDAR's model and ship fragments unless told; the
// flags' mistakes are named, and they go with --scene only.
TEST(FogctlTopologyScene, MappingFlagsChooseClusteringAndFragments) {
  ScratchDir dir("scene-mapping");
  const Outcome scene_made =
      fogctl({"scene", "moving", "--people", "2", "--vehicles", "1", "--lidars", "2", "--cameras", "0", "--out", "s.yaml"},
             dir.path());
  ASSERT_EQ(scene_made.code, 0) << describe(scene_made);
  const auto scene = sim::loadScene(dir.path() / "s.yaml");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const auto edgesOf = [](const TopologyConfig& t) {
    std::vector<const NodeConfig*> edges;
    for (const NodeConfig& n : t.nodes) {
      if (n.role == Role::kEdge) edges.push_back(&n);
    }
    return edges;
  };

  ASSERT_EQ(fogctl({"topology", "--scene", "s.yaml", "--out", "default.yaml"}, dir.path()).code, 0);
  const auto by_default = loadTopology(dir.path() / "default.yaml");
  ASSERT_TRUE(by_default.ok()) << by_default.error().message;
  EXPECT_EQ(by_default->madc.fragment_min_points, std::optional<std::size_t>(1));
  for (const NodeConfig* edge : edgesOf(*by_default)) {
    EXPECT_EQ(edge->sensor->clustering, ClusteringMode::kSensor);
    EXPECT_EQ(edge->sensor->model, scene->lidars[edge->id - 1].model);
  }

  const Outcome paper = fogctl({"topology", "--scene", "s.yaml", "--clustering", "exact", "--fragment-min-points", "off",
                                "--out", "paper.yaml"},
                               dir.path());
  ASSERT_EQ(paper.code, 0) << describe(paper);
  const auto exact = loadTopology(dir.path() / "paper.yaml");
  ASSERT_TRUE(exact.ok()) << exact.error().message;
  EXPECT_FALSE(exact->madc.fragment_min_points.has_value());
  for (const NodeConfig* edge : edgesOf(*exact)) EXPECT_EQ(edge->sensor->clustering, ClusteringMode::kExact);

  ASSERT_EQ(fogctl({"topology", "--scene", "s.yaml", "--fragment-min-points", "4", "--out", "four.yaml"}, dir.path()).code, 0);
  const auto four = loadTopology(dir.path() / "four.yaml");
  ASSERT_TRUE(four.ok()) << four.error().message;
  EXPECT_EQ(four->madc.fragment_min_points, std::optional<std::size_t>(4));

  const Outcome rings = fogctl({"topology", "--scene", "s.yaml", "--clustering", "rings"}, dir.path());
  EXPECT_EQ(rings.code, 2);
  EXPECT_TRUE(contains(rings.err, "--clustering must be exact")) << describe(rings);
  for (const char* bad : {"0", "1001", "some"}) {
    const Outcome fragments = fogctl({"topology", "--scene", "s.yaml", "--fragment-min-points", bad}, dir.path());
    EXPECT_EQ(fragments.code, 2) << bad;
    EXPECT_TRUE(contains(fragments.err, "--fragment-min-points must be off or in [1, 1000]")) << describe(fragments);
  }
  // --alpha-max below the topology's alpha (1.5) would make a topology every service refuses.
  const Outcome below = fogctl({"topology", "--scene", "s.yaml", "--alpha-max", "1.2", "--out", "below.yaml"}, dir.path());
  EXPECT_NE(below.code, 0);
  EXPECT_TRUE(contains(below.err, "madc.alpha_max")) << describe(below);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "below.yaml"));
  ASSERT_EQ(fogctl({"topology", "--scene", "s.yaml", "--alpha-max", "off", "--out", "off.yaml"}, dir.path()).code, 0);
  const auto off = loadTopology(dir.path() / "off.yaml");
  ASSERT_TRUE(off.ok()) << off.error().message;
  EXPECT_DOUBLE_EQ(off->madc.alpha_max, 0.0);
  EXPECT_DOUBLE_EQ(by_default->madc.alpha_max, 2.5);
  const Outcome scans = fogctl({"topology", "star", "--edges", "2", "--source", "scans", "--clustering", "sensor"}, dir.path());
  EXPECT_EQ(scans.code, 2);
  EXPECT_TRUE(contains(scans.err, "go with --scene")) << describe(scans);
}

// The compose file mounts its directory into every container: a simulated LiDAR's scene must lie
// inside it like any other file the topology names ("sim" itself is no file).
TEST(FogctlTopologyScene, ComposeWantsTheSceneFileInsideTheMountedDirectory) {
  ScratchDir dir("scene-compose");
  const fs::path project = dir.path() / "project";
  fs::create_directories(project);
  harness::ComposeOptions options;
  options.topology_file = project / "sim.yaml";
  options.project_dir = project;
  options.prometheus_config = "prometheus.yml";
  const sim::Scene scene = sim::randomScene(2, 2, 1);
  const auto inside = harness::composeFile(sim::sceneTopology(scene, project / "scenes" / "s.yaml"), options);
  EXPECT_TRUE(inside.ok()) << inside.error().message;
  const auto outside = harness::composeFile(sim::sceneTopology(scene, dir.path() / "s.yaml"), options);
  ASSERT_FALSE(outside.ok());
  EXPECT_TRUE(contains(outside.error().message, "edge-lidar-1's scene " + (dir.path() / "s.yaml").string() + " lies outside"))
      << outside.error().message;
}

// ---------------------------------------------------------------------------------------------
// topology --tracker --cameras: a tracker and HOG cameras on KITTI frames, and their deployment

// The bundled KITTI sequence copied into `dir` (scans, image_02 and calib.txt), as a user's data
// directory beside their topologies.
fs::path copyKittiSequence(const fs::path& dir) {
  const fs::path data = dir / "data" / "kitti_raw_seq_a";
  fs::create_directories(data.parent_path());
  fs::copy(fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a", data, fs::copy_options::recursive);
  return data;
}

TEST(FogctlTopologyCameras, ATrackerAndAHogCameraCalibratedFromTheKittiCalibFile) {
  ScratchDir dir("cameras");
  copyKittiSequence(dir.path());
  fs::create_directories(dir.path() / "topologies");
  const Outcome written = fogctl({"topology", "star", "--edges", "2", "--source", "../data/kitti_raw_seq_a", "--base-port", "45000",
                                  "--tracker", "--association", "paper", "--cameras", "../data/kitti_raw_seq_a/image_02",
                                  "--camera-rate-hz", "2", "--out", "topologies/star.yaml"},
                                 dir.path());
  ASSERT_EQ(written.code, 0) << describe(written);
  const std::string text = readFile(dir.path() / "topologies" / "star.yaml");
  EXPECT_TRUE(contains(text, "source: ../data/kitti_raw_seq_a/image_02")) << "written as given, relative to the topology";
  const auto topology = loadTopology(dir.path() / "topologies" / "star.yaml");
  ASSERT_TRUE(topology.ok()) << topology.error().message;
  const NodeConfig* tracker = topology->find("tracker");
  ASSERT_NE(tracker, nullptr);
  EXPECT_EQ(tracker->role, Role::kTracker);
  EXPECT_EQ(tracker->port, 45300);
  EXPECT_EQ(tracker->metrics_port, 45301);
  ASSERT_TRUE(tracker->tracker.has_value());
  EXPECT_EQ(tracker->tracker->tracking.association, tracking::Association::kPaper);
  const auto cameras = topology->camerasOf("tracker");
  ASSERT_EQ(cameras.size(), 1U);
  const NodeConfig& cam = *cameras[0];
  EXPECT_EQ(cam.name, "cam-image_02");
  EXPECT_EQ(cam.id, 401U);
  EXPECT_EQ(cam.metrics_port, 45401);
  ASSERT_TRUE(cam.camera.has_value());
  EXPECT_EQ(cam.camera->detector.kind, camera::DetectorKind::kHog);
  EXPECT_EQ(cam.camera->rate_hz, 2.0);
  EXPECT_EQ(fs::weakly_canonical(cam.camera->source), fs::weakly_canonical(dir.path() / "data" / "kitti_raw_seq_a" / "image_02"));
  // Camera 2 of calib.txt in the scans' frame: a point 20 m ahead of the Velodyne, on the road,
  // lands where P2 after R0_rect and Tr_velo_to_cam puts it (written and read back: within 0.01 px).
  const camera::PinholeCamera& k = cam.camera->calibration;
  EXPECT_EQ(k.width, 1242);
  EXPECT_EQ(k.height, 375);
  EXPECT_NEAR(k.fx, 721.5377, 1e-4);
  const auto pixel = k.project(Eigen::Vector3d(20.0, 0.0, -1.7));
  ASSERT_TRUE(pixel.has_value());
  Eigen::Matrix<double, 3, 4> p2;
  p2 << 7.215377e+02, 0, 6.095593e+02, 4.485728e+01, 0, 7.215377e+02, 1.728540e+02, 2.163791e-01, 0, 0, 1, 2.745884e-03;
  Eigen::Matrix3d r0;
  r0 << 9.999239e-01, 9.837760e-03, -7.445048e-03, -9.869795e-03, 9.999421e-01, -4.278459e-03, 7.402527e-03, 4.351614e-03, 9.999631e-01;
  Eigen::Matrix4d velo = Eigen::Matrix4d::Identity();
  velo.topRows<3>() << 7.533745e-03, -9.999714e-01, -6.166020e-04, -4.069766e-03, 1.480249e-02, 7.280733e-04, -9.998902e-01,
      -7.631618e-02, 9.998621e-01, 7.523790e-03, 1.480755e-02, -2.717806e-01;
  const Eigen::Vector4d rect = velo * Eigen::Vector4d(20.0, 0.0, -1.7, 1.0);
  const Eigen::Vector3d image = p2 * (Eigen::Vector4d() << r0 * rect.head<3>(), 1.0).finished();
  EXPECT_NEAR(pixel->x(), image.x() / image.z(), 0.01);
  EXPECT_NEAR(pixel->y(), image.y() / image.z(), 0.01);
}

TEST(FogctlTopologyCameras, BadCameraOptionsAreRefusedNamingWhatIsWrong) {
  ScratchDir dir("cameras-bad");
  const fs::path data = copyKittiSequence(dir.path());
  const std::vector<std::string> star{"topology", "star", "--edges", "2", "--source", "data/kitti_raw_seq_a"};
  const auto refused = [&](std::vector<std::string> extra, const std::string& why) {
    std::vector<std::string> args = star;
    args.insert(args.end(), extra.begin(), extra.end());
    const Outcome o = fogctl(args, dir.path());
    EXPECT_EQ(o.code, 2) << describe(o);
    EXPECT_TRUE(contains(o.err, why)) << describe(o);
  };
  refused({"--cameras", "data/kitti_raw_seq_a/image_02"}, "--cameras needs --tracker");
  refused({"--tracker", "--cameras", "data/kitti_raw_seq_a/nothing"}, "--cameras data/kitti_raw_seq_a/nothing: not a directory");
  fs::create_directories(dir.path() / "frames");
  fs::copy_file(data / "image_02" / "0000000000.png", dir.path() / "frames" / "0.png");
  refused({"--tracker", "--cameras", "frames"}, "cannot tell which camera of the calibration it is");
  fs::create_directories(dir.path() / "seq" / "image_02");
  fs::copy_file(data / "image_02" / "0000000000.png", dir.path() / "seq" / "image_02" / "0.png");
  refused({"--tracker", "--cameras", "seq/image_02"}, "cannot read its calibration");
  std::ofstream(dir.path() / "seq" / "calib.txt") << "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n";
  refused({"--tracker", "--cameras", "seq/image_02"}, "calib: no P1");
  fs::create_directories(dir.path() / "empty" / "image_02");
  refused({"--tracker", "--cameras", "empty/image_02", "--calib", "data/kitti_raw_seq_a/calib.txt"}, "no .png or .jpg image");
  refused({"--tracker", "--cameras", "data/kitti_raw_seq_a/image_02,data/kitti_raw_seq_a/image_02"}, "a second camera image_02");
  refused({"--tracker", "--cameras", "data/kitti_raw_seq_a/image_02", "--camera-rate-hz", "0"}, "--camera-rate-hz must be in (0, 1000]");
  refused({"--calib", "data/kitti_raw_seq_a/calib.txt"}, "--calib and --camera-rate-hz go with --cameras");
  refused({"--association", "paper"}, "--association goes with --tracker");
  refused({"--tracker", "--miss-rate", "0.3"}, "they go with --scene");
}

// The compose file runs the tracker after the root it reads and each camera after its tracker;
// a camera's frames must lie inside the mounted directory, and a V4L2 device is passed in.
TEST(FogctlTopologyCameras, ComposeRunsTheTrackerAndCamerasWithTheirFilesInsideTheMountedDirectory) {
  ScratchDir dir("cameras-compose");
  const fs::path project = dir.path() / "project";
  copyKittiSequence(project);
  const Outcome written = fogctl({"topology", "star", "--edges", "2", "--source", "data/kitti_raw_seq_a", "--tracker", "--cameras",
                                  "data/kitti_raw_seq_a/image_02", "--out", "star.yaml"},
                                 project);
  ASSERT_EQ(written.code, 0) << describe(written);
  auto topology = loadTopology(project / "star.yaml");
  ASSERT_TRUE(topology.ok()) << topology.error().message;
  harness::ComposeOptions options;
  options.topology_file = project / "star.yaml";
  options.project_dir = project;
  options.prometheus_config = "prometheus.yml";
  const auto compose = harness::composeFile(*topology, options);
  ASSERT_TRUE(compose.ok()) << compose.error().message;
  EXPECT_TRUE(contains(*compose, "  tracker:\n    image: fogmap:latest\n    command: [tracker, --topology, /fogmap/star.yaml, --node, tracker]\n"))
      << *compose;
  EXPECT_TRUE(contains(*compose, "    command: [detection, --topology, /fogmap/star.yaml, --node, cam-image_02]\n")) << *compose;
  // A service's lines: from "  NAME:" to the next line indented by two spaces only.
  const auto service = [&](const std::string& name) {
    std::string out;
    bool in = false;
    for (const std::string& line : lines(*compose)) {
      if (line.size() > 2 && line.rfind("  ", 0) == 0 && line[2] != ' ') in = line == "  " + name + ":";
      if (in) out += line + "\n";
    }
    return out;
  };
  EXPECT_TRUE(contains(service("tracker"), "depends_on: [sink]")) << service("tracker");
  EXPECT_TRUE(contains(service("cam-image_02"), "depends_on: [tracker]")) << service("cam-image_02");
  {
    TopologyConfig centroids = *topology;
    for (NodeConfig& n : centroids.nodes) {
      if (n.tracker) n.tracker->input = TrackerInput::kCentroids;
    }
    const auto without_root = harness::composeFile(centroids, options);
    ASSERT_TRUE(without_root.ok()) << without_root.error().message;
    EXPECT_TRUE(contains(*without_root, "--node, tracker]\n    network_mode: host\n    restart: unless-stopped\n    stop_grace_period: 10s\n"
                                        "    environment:\n      FOGMAP_METRICS: \"127.0.0.1:50301\"\n    volumes:\n      - .:/fogmap:ro\n  cam-image_02:"))
        << "a tracker fed by its edges' centroids does not wait for the root:\n" << *without_root;
  }
  EXPECT_TRUE(contains(service("cam-image_02"), "FOGMAP_METRICS: \"127.0.0.1:50401\"")) << service("cam-image_02");
  EXPECT_FALSE(contains(*compose, "devices:")) << "no device for a directory of frames";
  const std::string scrape = harness::prometheusConfig(*topology, {});
  EXPECT_TRUE(contains(scrape, "- targets: ['127.0.0.1:50301']\n        labels: {instance: tracker, role: tracker}")) << scrape;
  EXPECT_TRUE(contains(scrape, "- targets: ['127.0.0.1:50401']\n        labels: {instance: cam-image_02, role: detection}")) << scrape;

  TopologyConfig moved = *topology;
  const auto camera = [](TopologyConfig& t) -> CameraNodeConfig& {
    for (NodeConfig& n : t.nodes) {
      if (n.camera) return *n.camera;
    }
    throw std::logic_error("no camera");
  };
  camera(moved).source = dir.path() / "elsewhere";
  const auto outside = harness::composeFile(moved, options);
  ASSERT_FALSE(outside.ok());
  EXPECT_TRUE(contains(outside.error().message, "cam-image_02's camera source " + (dir.path() / "elsewhere").string() + " lies outside"))
      << outside.error().message;
  moved = *topology;
  camera(moved).detector.kind = camera::DetectorKind::kCascade;
  camera(moved).detector.cascade.cascade_path = (dir.path() / "faces.xml").string();
  const auto cascade = harness::composeFile(moved, options);
  ASSERT_FALSE(cascade.ok());
  EXPECT_TRUE(contains(cascade.error().message, "cam-image_02's cascade")) << cascade.error().message;
  moved = *topology;
  camera(moved).source = "/dev/video0";
  const auto device = harness::composeFile(moved, options);
  ASSERT_TRUE(device.ok()) << device.error().message;
  EXPECT_TRUE(contains(*device, "    devices: [\"/dev/video0:/dev/video0\"]\n    group_add: [video]\n")) << *device;
}

// ---------------------------------------------------------------------------------------------
// up --dry-run and compose check a topology before deploying it; no command aborts on one

// A fusion topology whose camera runs a cascade detector without saying which cascade: the parser
// accepts it (detector values are the detection service's to check); its scans and frames exist.
fs::path writeCascadeWithoutPath(const fs::path& dir) {
  fs::create_directories(dir / "scans");
  fs::create_directories(dir / "images");
  const fs::path file = dir / "cascade.yaml";
  std::ofstream(file) << "name: cascade\n"
                         "nodes:\n"
                         "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
                         "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans}}\n"
                         "  - {name: tracker, id: 300, role: tracker, port: 50300, metrics_port: 50301}\n"
                         "  - name: cam-1\n"
                         "    id: 401\n"
                         "    role: detection\n"
                         "    parent: tracker\n"
                         "    metrics_port: 50401\n"
                         "    camera:\n"
                         "      source: images\n"
                         "      detector: {kind: cascade}\n"
                         "      calibration: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480}\n";
  return file;
}

constexpr const char* kCascadeProblem = "node 'cam-1': camera.detector.cascade.cascade_path: is required";

TEST(FogctlCompose, RefusesACascadeWithoutItsPathNamingTheFieldAndWritesNothing) {
  ScratchDir dir("compose-cascade");
  writeCascadeWithoutPath(dir.path());
  const Outcome o = fogctl({"compose", "cascade.yaml", "--out", "compose.yaml", "--prometheus", "prometheus.yml"}, dir.path());
  EXPECT_TRUE(o.code == 1 || o.code == 2) << "refused, not aborted\n" << describe(o);
  EXPECT_TRUE(contains(o.err, std::string("cascade.yaml: ") + kCascadeProblem)) << describe(o);
  EXPECT_FALSE(fs::exists(dir.path() / "compose.yaml"));
  EXPECT_FALSE(fs::exists(dir.path() / "prometheus.yml"));
}

TEST(FogctlUp, DryRunRefusesACascadeWithoutItsPathAsUpDoesAndStartsNothing) {
  ScratchDir dir("up-cascade");
  writeCascadeWithoutPath(dir.path());
  for (const bool dry_run : {true, false}) {
    std::vector<std::string> args{"up", "cascade.yaml"};
    if (dry_run) args.push_back("--dry-run");
    const Outcome o = fogctl(args, dir.path(), 30s);
    EXPECT_TRUE(o.code == 1 || o.code == 2) << "refused, not aborted\n" << describe(o);
    EXPECT_TRUE(contains(o.err, std::string("cascade.yaml: ") + kCascadeProblem)) << describe(o);
    EXPECT_FALSE(contains(o.out, "would start")) << describe(o);
  }
  EXPECT_FALSE(fs::exists(dir.path() / ".fogmap")) << "no state directory, no logs: nothing was started";
}

TEST(FogctlUp, DryRunPrintsEveryServiceServersFirstAndStartsNothing) {
  ScratchDir dir("up-dry-run");
  const fs::path topology = writeTopology(dir.path(), "dry-star");
  ASSERT_FALSE(topology.empty());
  const Outcome o = fogctl({"up", topology.string(), "--dry-run", "--state", "state"}, dir.path(), 30s);
  ASSERT_EQ(o.code, 0) << describe(o);
  const auto sink = o.out.find("would start sink (aggregator): ");
  const auto edge = o.out.find("would start edge-1 (edge): ");
  ASSERT_NE(sink, std::string::npos) << describe(o);
  ASSERT_NE(edge, std::string::npos) << describe(o);
  EXPECT_LT(sink, edge) << "the root is started before its edge\n" << describe(o);
  EXPECT_TRUE(contains(o.out, "edge-cluster --topology " + topology.string() + " --node edge-1\n")) << describe(o);
  EXPECT_TRUE(contains(o.out, "2 services")) << describe(o);
  EXPECT_TRUE(contains(o.out, "nothing started")) << describe(o);
  EXPECT_FALSE(fs::exists(dir.path() / "state")) << "a dry run creates no state directory";
}

// The same topology in process: parsed, then refused by the check up and compose run, by up's plan,
// and answered (not thrown at) by the compose generation that has no check of its own.
TEST(FogctlChecks, ACascadeWithoutItsPathIsRefusedInProcessWithoutThrowing) {
  ScratchDir dir("checks-cascade");
  const fs::path file = writeCascadeWithoutPath(dir.path());
  const auto topology = loadTopology(file);
  ASSERT_TRUE(topology.ok()) << "the parser leaves detector values to the services: " << topology.error().message;

  const Status startable = harness::checkStartable(*topology);
  ASSERT_FALSE(startable.ok());
  EXPECT_EQ(startable.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(startable.error().message, kCascadeProblem);
  const auto loaded = harness::loadStartableTopology(file);
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.error().message, file.string() + ": " + kCascadeProblem);
  const auto plan = harness::planCluster(file, *topology, dir.path() / "state");
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.error().message, kCascadeProblem);
  EXPECT_FALSE(fs::exists(dir.path() / "state"));

  harness::ComposeOptions options;
  options.topology_file = file;
  options.project_dir = dir.path();
  options.prometheus_config = "prometheus.yml";
  Expected<std::string> compose = invalidArgument("not run");
  ASSERT_NO_THROW(compose = harness::composeFile(*topology, options));
  ASSERT_FALSE(compose.ok());
  EXPECT_TRUE(contains(compose.error().message, "cam-1's cascade: no path given")) << compose.error().message;
}

TEST(FogctlChecks, AMissingInputFileIsRefusedNamingTheNodeAndField) {
  ScratchDir dir("checks-missing");
  const fs::path file = writeCascadeWithoutPath(dir.path());
  auto topology = loadTopology(file);
  ASSERT_TRUE(topology.ok()) << topology.error().message;
  for (NodeConfig& node : topology->nodes) {
    if (node.camera) node.camera->detector.kind = camera::DetectorKind::kHog;
  }
  EXPECT_TRUE(harness::checkStartable(*topology).ok()) << harness::checkStartable(*topology).error().message;
  fs::remove(dir.path() / "images");
  const Status missing = harness::checkStartable(*topology);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_EQ(missing.error().message,
            "node 'cam-1': camera.source: no such file or directory: " + (dir.path() / "images").string());
}

// A topology read by its bare file name has the working directory as its own: a CA named beside
// it leaves the certificate directory empty, which compose once took for a path to resolve.
TEST(FogctlCompose, ATlsTopologyInTheWorkingDirectoryIsDeployed) {
  ScratchDir dir("compose-tls-here");
  fs::create_directories(dir.path() / "scans");
  std::ofstream(dir.path() / "tls-here.yaml")
      << "name: tls-here\n"
         "tls: {ca: ca.crt}\n"
         "nodes:\n"
         "  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}\n"
         "  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: scans}}\n";
  const Outcome o = fogctl({"compose", "tls-here.yaml", "--out", "compose.yaml", "--prometheus", "prometheus.yml"}, dir.path());
  ASSERT_EQ(o.code, 0) << describe(o);
  EXPECT_TRUE(contains(readFile(dir.path() / "compose.yaml"), "#   fogctl certs tls-here.yaml --out . --owner 10001\n"))
      << readFile(dir.path() / "compose.yaml");
}

TEST(FogctlPaths, EmptyPathsAreRefusedWithAMessageNeverAnAbort) {
  ScratchDir dir("empty-paths");
  const fs::path topology = writeTopology(dir.path(), "empty-paths");
  ASSERT_FALSE(topology.empty());
  for (const auto& args : {std::vector<std::string>{"up", topology.string(), "--dry-run", "--state", ""},
                           std::vector<std::string>{"up", "", "--dry-run"},
                           std::vector<std::string>{"down", "--state", ""},
                           std::vector<std::string>{"compose", topology.string(), "--out", ""},
                           std::vector<std::string>{"compose", topology.string(), "--prometheus", ""},
                           std::vector<std::string>{"certs", "", "--out", "certs"},
                           std::vector<std::string>{"faults", ""},
                           std::vector<std::string>{"watch", ""}}) {
    const Outcome o = fogctl(args, dir.path(), 30s);
    std::string line;
    for (const auto& a : args) line += "'" + a + "' ";
    EXPECT_TRUE(o.code == 1 || o.code == 2) << line << "\n" << describe(o);
    EXPECT_FALSE(o.err.empty()) << line << "\n" << describe(o);
  }
}

}  // namespace
}  // namespace fogmap
