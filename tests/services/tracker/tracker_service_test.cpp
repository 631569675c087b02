// The tracker service: a global map's objects as LiDAR observations (against the closed form), the
// adapter over real gRPC on loopback (detections and centroid frames in, refusals counted, tracks
// out to a subscriber), epochs of centroids fused at their deadline, the metrics, and the feed
// that follows a root which goes away and comes back.
#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/perception/box_fitting.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/proto_convert.hpp"
#include "services/tracker/global_map_feed.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"
#include "services/tracker/tracker_service.hpp"
#include "tests/support/fake_root.hpp"
#include "tests/support/front_camera.hpp"
#include "tests/support/metric_values.hpp"
#include "tests/support/epoch_times.hpp"
#include "tests/support/global_maps.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

using test_support::globalMapWith;
using test_support::kMs;

Ellipsoid ellipsoidAt(std::uint32_t node, std::uint32_t index, const Eigen::Vector3d& centre, const Eigen::Matrix3d& shape,
                      std::uint64_t points) {
  Ellipsoid e;
  e.id = {node, 1, index};
  e.center = centre;
  e.shape = shape;
  e.point_count = points;
  return e;
}

using test_support::frontCamera;

TEST(TrackerNode, AnObjectsObservationIsThePointWeightedCentroidAndTheMixtureCovariance) {
  // Two ellipsoids of shapes alpha^2 Sigma_i: 30 points at (0,0,0), 10 at (4,0,0), alpha 2.
  const double alpha = 2.0;
  const Eigen::Matrix3d sigma1 = Eigen::Vector3d(0.1, 0.2, 0.3).asDiagonal();
  const Eigen::Matrix3d sigma2 = Eigen::Vector3d(0.5, 0.1, 0.1).asDiagonal();
  GlobalMapMessage g;
  g.header.sensor_time_ns = 42;
  const std::vector<Ellipsoid> parts{ellipsoidAt(1, 0, {0, 0, 0}, alpha * alpha * sigma1, 30),
                                     ellipsoidAt(2, 0, {4, 0, 0}, alpha * alpha * sigma2, 10)};
  const std::vector<std::size_t> one_object{0, 0};
  g.map = mapFromGroups(parts, one_object);
  const auto frame = observationsOf(g, alpha);
  EXPECT_EQ(frame.time_ns, 42);
  ASSERT_EQ(frame.observations.size(), 1U);
  EXPECT_LT((frame.observations[0].position - Eigen::Vector3d(1, 0, 0)).norm(), 1e-12);
  // Within: (30 sigma1 + 10 sigma2) / 40; between: (30 * 1^2 + 10 * 3^2) / 40 = 3 along x.
  Eigen::Matrix3d expected = (30.0 * sigma1 + 10.0 * sigma2) / 40.0;
  expected(0, 0) += 3.0;
  EXPECT_LT((frame.observations[0].covariance - expected).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(TrackerNode, ObjectsStackedOrTouchingOnTheGroundAreOneObstacleAndSeparateOnesStayApart) {
  // A person cut into three slices by the LiDAR's rings (one above the other), a car's two halves
  // with 0.12 m between their boxes, and a pole 1.76 m from the car.
  const Eigen::Matrix3d small = Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal() * 2.25;
  const Eigen::Matrix3d half_car = Eigen::Vector3d(0.8, 0.3, 0.1).asDiagonal() * 2.25;
  const std::vector<Ellipsoid> parts{
      ellipsoidAt(1, 0, {5, 0, 0.4}, small, 20),   ellipsoidAt(1, 1, {5, 0, 0.8}, small, 20),
      ellipsoidAt(1, 2, {5.05, 0, 1.2}, small, 20), ellipsoidAt(1, 3, {10, 0, 0.5}, half_car, 40),
      ellipsoidAt(1, 4, {12.8, 0, 0.5}, half_car, 40), ellipsoidAt(1, 5, {16.2, 0, 0.5}, small, 10)};
  GlobalMapMessage g;
  g.map = localMap(parts);
  ASSERT_EQ(g.map.objects.size(), 6U);
  const auto frame = observationsOf(g, 1.5, 0.3);
  ASSERT_EQ(frame.observations.size(), 3U);
  std::vector<double> xs;
  for (const auto& o : frame.observations) xs.push_back(o.position.x());
  std::sort(xs.begin(), xs.end());
  EXPECT_NEAR(xs[0], (5 + 5 + 5.05) / 3.0, 1e-9);
  EXPECT_NEAR(xs[1], 11.4, 1e-9);
  EXPECT_NEAR(xs[2], 16.2, 1e-9);
  // Without growing, the slices (whose footprints overlap) are still one; the car's halves are two.
  EXPECT_EQ(observationsOf(g, 1.5, 0.0).observations.size(), 4U);
}

TEST(TrackerNode, AVehicleIsObservedAtTheCentreOfItsBoxGrownFromTheFaceSeenAndAPersonAtItsPoints) {
  // A car whose rear face (x = 20) one LiDAR saw: points over its rear 1.2 m; a person at (5, -3).
  Ellipsoid rear = ellipsoidAt(1, 0, {20.6, 3.0, 0.7}, Eigen::Vector3d(0.4, 1.0, 0.3).asDiagonal(), 120);
  OrientedBox box;
  box.centre = Eigen::Vector3d(20.6, 3.0, 0.7);
  box.length = 1.8;
  box.width = 1.2;
  box.yaw = -std::numbers::pi / 2;
  box.anchor = box.anchorFor(Eigen::Vector3d(0.0, 3.0, 1.7));
  rear.box = box;
  rear.label = ObjectLabel{ObjectClass::kCar, 0.8};
  Ellipsoid person = ellipsoidAt(1, 1, {5.0, -3.0, 0.9}, Eigen::Vector3d(0.05, 0.05, 0.3).asDiagonal(), 40);
  OrientedBox person_box;
  person_box.centre = Eigen::Vector3d(5.1, -3.0, 0.9);
  person_box.length = 0.5;
  person_box.width = 0.4;
  person_box.height = 1.7;
  person.box = person_box;
  person.label = ObjectLabel{ObjectClass::kPerson, 0.9};
  GlobalMapMessage g;
  g.map = localMap({rear, person});
  const auto frame = observationsOf(g, 1.5);
  ASSERT_EQ(frame.observations.size(), 2U);
  const auto& car = frame.observations[0].position.x() > 10 ? frame.observations[0] : frame.observations[1];
  const auto& walker = frame.observations[0].position.x() > 10 ? frame.observations[1] : frame.observations[0];
  EXPECT_NEAR(car.position.x(), 22.2, 1e-6);  // rear face at 20, 4.4 m long
  EXPECT_NEAR(car.position.y(), 3.0, 1e-6);
  EXPECT_NEAR(car.covariance(0, 0), kVehicleCentreSigmaM * kVehicleCentreSigmaM, 1e-12);
  ASSERT_TRUE(car.lidar_class.has_value());
  EXPECT_EQ(car.lidar_class->object_class, ObjectClass::kCar);
  ASSERT_TRUE(car.box.has_value());
  EXPECT_NEAR(car.box->length, 1.8, 1e-9);  // as the view gives it
  EXPECT_LT((walker.position - Eigen::Vector3d(5.0, -3.0, 0.9)).norm(), 1e-12);  // its points' mean
  EXPECT_EQ(walker.lidar_class->object_class, ObjectClass::kPerson);
}

// A person, an upright cylinder of radius 0.25 m at (10, 0): what a LiDAR at `sensor` sees of it
// (the half facing it) as the edge ships it, an ellipsoid at its points' mean with the box fitted
// with the sensor (anchored on the face toward it) and the class person.
Ellipsoid personView(std::uint32_t node, const Eigen::Vector3d& sensor, Eigen::Vector3d* points_mean) {
  constexpr double kRadius = 0.25;
  const Eigen::Vector2d axis(10.0, 0.0);
  const Eigen::Vector2d toward = (sensor.head<2>() - axis).normalized();
  const Eigen::Vector2d side(-toward.y(), toward.x());
  Cloud points;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int k = -20; k <= 20; ++k) {
    const double theta = k * (std::numbers::pi / 2) / 20;
    const Eigen::Vector2d at = axis + kRadius * (std::cos(theta) * toward + std::sin(theta) * side);
    for (double z = 0.2; z <= 1.6; z += 0.2) {
      points.push_back({static_cast<float>(at.x()), static_cast<float>(at.y()), static_cast<float>(z)});
      mean += Eigen::Vector3d(at.x(), at.y(), z);
    }
  }
  mean /= static_cast<double>(points.size());
  *points_mean = mean;
  Ellipsoid view = ellipsoidAt(node, 0, mean, Eigen::Vector3d(0.05, 0.15, 0.4).asDiagonal(), points.size());
  const auto box = fitOrientedBox(points, sensor);
  EXPECT_TRUE(box.ok());
  EXPECT_NE(box->anchor, BoxAnchor::kNone);
  view.box = *box;
  view.label = ObjectLabel{ObjectClass::kPerson, 0.9};
  return view;
}

// A LiDAR sees a person's near half: its points' mean lies 0.2 m short of the axis, toward it.
// Each view counts at the centre of its box grown to a square away from the face seen: one view,
// and two from LiDARs at right angles, give the axis.
TEST(TrackerNode, APersonIsObservedOnItsAxisNotOnTheSidesItsSensorsSaw) {
  const Eigen::Vector2d axis(10.0, 0.0);
  Eigen::Vector3d mean_a, mean_b;
  const Ellipsoid a = personView(1, Eigen::Vector3d(0.0, 0.0, 1.7), &mean_a);
  const Ellipsoid b = personView(2, Eigen::Vector3d(10.0, -10.0, 1.7), &mean_b);
  ASSERT_GT((mean_a.head<2>() - axis).norm(), 0.1) << "the points' mean must be off the axis for the case to test anything";
  ASSERT_GT((0.5 * (mean_a + mean_b).head<2>() - axis).norm(), 0.1) << "and so must the mean of the two views";
  for (const std::vector<Ellipsoid>& views : {std::vector<Ellipsoid>{a}, std::vector<Ellipsoid>{a, b}}) {
    GlobalMapMessage g;
    g.map = localMap(views);
    const auto frame = observationsOf(g, 1.5);
    ASSERT_EQ(frame.observations.size(), 1U) << views.size() << " views";
    EXPECT_LT((frame.observations[0].position.head<2>() - axis).norm(), 0.03) << views.size() << " views";
    EXPECT_NEAR(frame.observations[0].position.z(), mean_a.z(), 1e-9);
  }
}

TEST(TrackerNode, TheTwoPartsOfACarTheMapHoldsApartAreOneObservationAtTheCarsCentre) {
  // A car 4.4 x 1.8 m at (20, 3) along x, cut by its sensors into a rear part (x 17.8 to 19.3) and
  // a front part (x 20.8 to 22.2), 1.5 m apart: two objects on the map, one car.
  const auto part = [](std::uint32_t node, double x0, double x1, BoxAnchor anchor) {
    Ellipsoid e = ellipsoidAt(node, 0, {0.5 * (x0 + x1), 3.0, 0.7}, Eigen::Vector3d(0.3, 0.8, 0.3).asDiagonal(), 60);
    OrientedBox box;
    box.centre = Eigen::Vector3d(0.5 * (x0 + x1), 3.0, 0.7);
    box.length = 1.8;
    box.width = x1 - x0;
    box.yaw = -std::numbers::pi / 2;
    box.anchor = anchor;
    e.box = box;
    e.label = ObjectLabel{ObjectClass::kCar, 0.7};
    return e;
  };
  // One sensor behind the car (x < 17.8), one ahead of it (x > 22.2): each part's anchor is the
  // face toward its sensor.
  Ellipsoid rear = part(1, 17.8, 19.3, BoxAnchor::kNone);
  rear.box->anchor = rear.box->anchorFor(Eigen::Vector3d(0.0, 3.0, 1.7));
  Ellipsoid front = part(2, 20.8, 22.2, BoxAnchor::kNone);
  front.box->anchor = front.box->anchorFor(Eigen::Vector3d(40.0, 3.0, 1.7));
  GlobalMapMessage g;
  g.map = localMap({rear, front});
  ASSERT_EQ(g.map.objects.size(), 2U);
  const auto frame = observationsOf(g, 1.5);
  ASSERT_EQ(frame.observations.size(), 1U);
  EXPECT_NEAR(frame.observations[0].position.x(), 20.0, 0.05);
  EXPECT_NEAR(frame.observations[0].position.y(), 3.0, 0.05);
}

TEST(TrackerNode, LateRevisionsAreNotFusedTwice) {
  auto tracker = tracking::Tracker::create({}, {});
  ASSERT_TRUE(tracker.ok());
  int published = 0;
  TrackerNode node(std::move(*tracker), 1.5, [] { return std::int64_t{1000} * kMs; },
                   [&](const TrackSnapshot&, const FusionReport& report) {
                     ++published;
                     EXPECT_EQ(report.steps.size(), 1U);
                     EXPECT_DOUBLE_EQ(report.end_to_end_seconds, 0.1);
                   });
  node.addGlobalMap(globalMapWith(900 * kMs, {{5, 0, 0.5}}));  // no cameras: nothing to wait for
  auto revision = globalMapWith(900 * kMs, {{5, 0, 0.5}});
  revision.late = true;
  revision.revision = 1;
  node.addGlobalMap(revision);
  EXPECT_EQ(published, 1);
  EXPECT_EQ(node.counters().steps, 1U);
}

TEST(TrackerNode, ALateFirstPublicationIsStillFused) {
  // The root fell behind and published the next epoch late (flagged): its picture is the only
  // one of that instant, so the tracker takes it.
  auto tracker = tracking::Tracker::create({}, {});
  ASSERT_TRUE(tracker.ok());
  int published = 0;
  TrackerNode node(std::move(*tracker), 1.5, [] { return std::int64_t{1200} * kMs; },
                   [&](const TrackSnapshot&, const FusionReport&) { ++published; });
  node.addGlobalMap(globalMapWith(900 * kMs, {{5, 0, 0.5}}));
  auto late = globalMapWith(1000 * kMs, {{5.1, 0, 0.5}});
  late.late = true;
  node.addGlobalMap(late);
  EXPECT_EQ(published, 2);
  EXPECT_EQ(node.counters().steps, 2U);
}

TEST(TrackerNode, AGlobalMapWithoutSensorTimeHasNoDataAndIsNotFused) {
  auto tracker = tracking::Tracker::create({}, {});
  ASSERT_TRUE(tracker.ok());
  std::vector<double> end_to_end;
  TrackerNode node(std::move(*tracker), 1.5, [] { return std::int64_t{1000} * kMs; },
                   [&](const TrackSnapshot&, const FusionReport& report) { end_to_end.push_back(report.end_to_end_seconds); });
  // Every node failed the epoch: the root publishes it with sensor time 0 (unknown).
  node.addGlobalMap(globalMapWith(0, {{5, 0, 0.5}}));
  EXPECT_TRUE(end_to_end.empty());
  EXPECT_EQ(node.counters().steps, 0U);
  node.addGlobalMap(globalMapWith(900 * kMs, {{5, 0, 0.5}}));
  ASSERT_EQ(end_to_end.size(), 1U);
  EXPECT_DOUBLE_EQ(end_to_end.front(), 0.1);
}

TEST(TrackerNode, ACameraNotHeardFromIsStaleSinceTheStartAndFreshOnceItsFramesCome) {
  auto tracker = tracking::Tracker::create({}, {frontCamera()});
  ASSERT_TRUE(tracker.ok());
  std::atomic<std::int64_t> now{1000 * kMs};
  std::vector<std::map<std::string, double>> staleness;
  TrackerNode node(std::move(*tracker), 1.5, [&] { return now.load(); },
                   [&](const TrackSnapshot&, const FusionReport& report) { staleness.push_back(report.camera_staleness_s); });
  // The LiDAR frame at 2.9 s waits for the camera at most max_detection_wait_s (0.25 s).
  now = 3000 * kMs;
  node.addGlobalMap(globalMapWith(2900 * kMs, {{5, 0, 0.5}}));
  EXPECT_TRUE(staleness.empty());
  now = 3200 * kMs;
  node.tick();
  ASSERT_EQ(staleness.size(), 1U);
  EXPECT_NEAR(staleness.back().at("cam-1"), 2.2, 1e-9) << "stale since the node started at 1 s";
  // The camera's first frame, captured at 3.25 s, arrives; the next LiDAR frame fuses with it.
  node.addDetections(tracking::DetectionFrame{"cam-1", 3250 * kMs, {}});
  now = 3300 * kMs;
  node.addGlobalMap(globalMapWith(3200 * kMs, {{5, 0, 0.5}}));
  ASSERT_EQ(staleness.size(), 2U);
  EXPECT_NEAR(staleness.back().at("cam-1"), 0.05, 1e-9);
}

// A tracker core behind its adapter on a loopback server; with `edges`, its input is their
// centroids (epochs of 100 ms, deadline 80 ms).
class TrackerServer {
 public:
  explicit TrackerServer(std::vector<camera::PinholeCamera> cameras, std::vector<std::string> edges = {}) {
    auto tracker = tracking::Tracker::create({}, cameras);
    EXPECT_TRUE(tracker.ok());
    std::vector<std::string> names;
    for (const auto& c : cameras) names.push_back(c.name);
    std::optional<CentroidCollector> collector;
    if (!edges.empty()) {
      auto schedule = EpochSchedule::create(100.0, 80.0);
      EXPECT_TRUE(schedule.ok());
      collector.emplace(CentroidCollectorConfig{edges, 1.0, 3.0}, *schedule);
    }
    node_ = std::make_unique<TrackerNode>(
        std::move(*tracker), 1.5, [this] { return now_ns.load(); },
        [this](const TrackSnapshot& s, const FusionReport&) { service_->publish(s); }, std::move(collector));
    TrackerServiceHooks hooks;
    hooks.on_detections = [this](const std::string&, std::size_t) {
      std::lock_guard lock(mutex_);
      ++accepted_;
      changed_.notify_all();
    };
    hooks.on_refused = [this](const std::string&, const std::string& why) {
      std::lock_guard lock(mutex_);
      refusals_.push_back(why);
      changed_.notify_all();
    };
    hooks.on_centroids = [this](const std::string& edge, std::size_t bytes) {
      EXPECT_GT(bytes, 0U);
      std::lock_guard lock(mutex_);
      centroid_frames_.push_back(edge);
      changed_.notify_all();
    };
    hooks.on_centroids_refused = [this](const std::string& reason, const std::string& why) {
      std::lock_guard lock(mutex_);
      centroid_refusals_.push_back({reason, why});
      changed_.notify_all();
    };
    service_ = std::make_unique<TrackerService>(*node_, names, false, hooks, 16, 20ms);
    grpc::ServerBuilder builder;
    configureServer(builder, 4U << 20);
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(service_.get());
    server_ = builder.BuildAndStart();
  }
  ~TrackerServer() {
    service_->shutdown(200ms);
    server_->Shutdown(std::chrono::system_clock::now() + 500ms);
  }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  TrackerNode& node() { return *node_; }
  TrackerService& service() { return *service_; }
  // Waits (bounded) until `accepted` frames were taken and `refused` refused.
  bool waitFor(int accepted, std::size_t refused) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, 5s, [&] { return accepted_ >= accepted && refusals_.size() >= refused; });
  }
  std::vector<std::string> refusals() {
    std::lock_guard lock(mutex_);
    return refusals_;
  }
  // Waits (bounded) until `accepted` centroid frames were taken and `refused` refused.
  bool waitForCentroids(std::size_t accepted, std::size_t refused) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, 5s, [&] { return centroid_frames_.size() >= accepted && centroid_refusals_.size() >= refused; });
  }
  std::vector<std::pair<std::string, std::string>> centroidRefusals() {
    std::lock_guard lock(mutex_);
    return centroid_refusals_;
  }
  std::atomic<std::int64_t> now_ns{0};

 private:
  std::unique_ptr<TrackerNode> node_;
  std::unique_ptr<TrackerService> service_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  std::mutex mutex_;
  std::condition_variable changed_;
  int accepted_ = 0;
  std::vector<std::string> refusals_;
  std::vector<std::string> centroid_frames_;
  std::vector<std::pair<std::string, std::string>> centroid_refusals_;
};

TEST(TrackerService, DetectionsPushedOverGrpcAreFusedAndBadFramesAreRefusedAndCounted) {
  const auto cam = frontCamera();
  TrackerServer server({cam});
  auto channel = makeChannel(server.target(), 4U << 20);
  auto stub = v1::TrackerService::NewStub(channel);

  // A subscriber first, so it sees the first tracks.
  grpc::ClientContext sub_context;
  sub_context.set_wait_for_ready(true);  // a loaded machine may be slow to connect: wait, do not fail
  v1::TrackSubscribeRequest request;
  request.set_include_tentative(true);
  auto tracks = stub->Subscribe(&sub_context, request);
  for (int i = 0; i < 100 && server.service().subscriberCount() == 0; ++i) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(server.service().subscriberCount(), 1U);

  server.now_ns = 1000 * kMs;  // the frames are captured now
  grpc::ClientContext context;
  context.set_wait_for_ready(true);
  v1::DetectionSummary summary;
  auto writer = stub->PushDetections(&context, &summary);
  // A person 8 m ahead: the pixel of (8, 0, 0.5) is (320, 271.25).
  tracking::DetectionFrame good{"cam-1", 1000 * kMs, {}};
  camera::Detection person;
  person.box = {300, 250, 340, 290};
  person.label = "person";
  person.score = 0.9;
  good.detections.push_back(person);
  ASSERT_TRUE(writer->Write(toProto(good)));
  v1::DetectionFrame bad = toProto(good);
  bad.mutable_detections(0)->set_left(std::nanf(""));
  ASSERT_TRUE(writer->Write(bad));
  v1::DetectionFrame stranger = toProto(good);
  stranger.set_camera("cam-9");
  ASSERT_TRUE(writer->Write(stranger));
  ASSERT_TRUE(server.waitFor(1, 2));
  const auto refusals = server.refusals();
  EXPECT_NE(refusals[0].find("detections[0]: box coordinates must be finite"), std::string::npos) << refusals[0];
  EXPECT_NE(refusals[1].find("'cam-9' is not a camera of this tracker"), std::string::npos) << refusals[1];
  ASSERT_TRUE(writer->WritesDone());
  ASSERT_TRUE(writer->Finish().ok());
  EXPECT_EQ(summary.received(), 3U);
  EXPECT_EQ(summary.refused(), 2U);

  // The global map of the same instant: the person is fused, the track is published.
  server.now_ns = 1010 * kMs;
  server.node().addGlobalMap(globalMapWith(1000 * kMs, {{8, 0, 0.5}, {20, 10, 0.5}}));
  v1::TrackList list;
  ASSERT_TRUE(tracks->Read(&list));
  EXPECT_EQ(list.lidar_time_ns(), 1000 * kMs);
  EXPECT_EQ(list.published_time_ns(), 1010 * kMs);
  EXPECT_EQ(list.association(), "kalman");
  ASSERT_EQ(list.tracks_size(), 2);
  int labelled = 0;
  for (const auto& proto : list.tracks()) {
    const auto t = fromProto(proto);
    ASSERT_TRUE(t.ok()) << t.error().message;
    if (t->label == "person") {
      ++labelled;
      EXPECT_TRUE(t->camera_confirmed);
      EXPECT_EQ(t->state, tracking::TrackState::kConfirmed);
      EXPECT_LT((t->position - Eigen::Vector2d(8, 0)).norm(), 1e-9);
    } else {
      EXPECT_EQ(t->state, tracking::TrackState::kTentative);  // LiDAR alone: not confirmed yet
    }
  }
  EXPECT_EQ(labelled, 1);
  sub_context.TryCancel();
}

TEST(TrackerService, CentroidFramesPushedOverGrpcAreFusedPerEpochAndMalformedOnesAreRefusedAndCounted) {
  TrackerServer server({}, {"edge-a", "edge-b"});
  const std::int64_t epoch_start = 1'700'000'000'000'000'000;  // epoch 17e9 of 100 ms
  const std::uint64_t epoch = 17'000'000'000;
  server.now_ns = epoch_start + 20 * kMs;
  auto stub = v1::TrackerService::NewStub(makeChannel(server.target(), 4U << 20));
  grpc::ClientContext context;
  context.set_wait_for_ready(true);
  v1::CentroidSummary summary;
  auto writer = stub->PushCentroids(&context, &summary);

  tracking::CentroidFrame a;
  a.edge = "edge-a";
  a.epoch = epoch;
  a.time_ns = epoch_start + 3 * kMs;
  a.centroids.push_back({Eigen::Vector3d(4.0, 1.0, 0.9), Eigen::Matrix3d::Identity() * 0.04, 30});
  tracking::CentroidFrame b = a;
  b.edge = "edge-b";
  b.centroids[0].position = Eigen::Vector3d(4.5, 1.0, 0.9);  // the same person from the other side
  ASSERT_TRUE(writer->Write(toProto(a)));
  // Non-finite, a covariance of the wrong size, a negative variance, a stranger, a duplicate.
  v1::CentroidFrame nan = toProto(b);
  nan.mutable_centroids(0)->set_position(1, std::nanf(""));
  ASSERT_TRUE(writer->Write(nan));
  v1::CentroidFrame short_covariance = toProto(b);
  short_covariance.mutable_centroids(0)->mutable_covariance()->RemoveLast();
  ASSERT_TRUE(writer->Write(short_covariance));
  v1::CentroidFrame negative = toProto(b);
  negative.mutable_centroids(0)->set_covariance(5, -1.0F);
  ASSERT_TRUE(writer->Write(negative));
  tracking::CentroidFrame stranger = b;
  stranger.edge = "edge-z";
  ASSERT_TRUE(writer->Write(toProto(stranger)));
  ASSERT_TRUE(writer->Write(toProto(a)));
  ASSERT_TRUE(server.waitForCentroids(1, 5));
  EXPECT_TRUE(server.node().tracks().empty()) << "the epoch waits for edge-b";
  ASSERT_TRUE(writer->Write(toProto(b)));
  ASSERT_TRUE(server.waitForCentroids(2, 5));
  ASSERT_TRUE(writer->WritesDone());
  ASSERT_TRUE(writer->Finish().ok());
  EXPECT_EQ(summary.received(), 7U);
  EXPECT_EQ(summary.refused(), 5U);

  const auto refusals = server.centroidRefusals();
  ASSERT_EQ(refusals.size(), 5U);
  const std::vector<std::string> reasons{"malformed", "malformed", "malformed", "unknown_edge", "duplicate"};
  const std::vector<std::string> phrases{"centroids[0]: position must be finite", "covariance has 5 values, expected 6",
                                         "not positive semi-definite", "edge 'edge-z'", "edge 'edge-a'"};
  for (std::size_t i = 0; i < refusals.size(); ++i) {
    EXPECT_EQ(refusals[i].first, reasons[i]) << refusals[i].second;
    EXPECT_NE(refusals[i].second.find(phrases[i]), std::string::npos) << refusals[i].second;
  }
  // The epoch is complete: one LiDAR frame, the two views merged into one tentative track between them.
  const auto tracks = server.node().tracks();
  ASSERT_EQ(tracks.size(), 1U);
  EXPECT_LT((tracks[0].position - Eigen::Vector2d(4.25, 1.0)).norm(), 1e-9);
  EXPECT_EQ(server.node().counters().steps, 1U);
  ASSERT_TRUE(server.node().centroidCounters().has_value());
  EXPECT_EQ(server.node().centroidCounters()->frames_accepted, 2U);
}

TEST(TrackerNode, AnEpochOfCentroidsAnEdgeMissedIsFusedAtItsDeadlineOnTick) {
  std::atomic<std::int64_t> now{1'700'000'000'000'000'000};
  auto tracker = tracking::Tracker::create({}, {});
  ASSERT_TRUE(tracker.ok());
  auto schedule = EpochSchedule::create(100.0, 80.0);
  ASSERT_TRUE(schedule.ok());
  std::vector<std::int64_t> published;
  TrackerNode node(std::move(*tracker), 1.5, [&] { return now.load(); },
                   [&](const TrackSnapshot& s, const FusionReport& report) {
                     published.push_back(s.lidar_time_ns);
                     ASSERT_TRUE(report.centroids.has_value());
                     EXPECT_EQ(report.centroids->epochs_partial, 1U);
                   },
                   CentroidCollector(CentroidCollectorConfig{{"edge-a", "edge-b"}, 1.0, 3.0}, *schedule));
  tracking::CentroidFrame a;
  a.edge = "edge-a";
  a.epoch = 17'000'000'000;
  a.time_ns = now.load() + 1 * kMs;
  a.centroids.push_back({Eigen::Vector3d(2.0, 0.0, 1.0), Eigen::Matrix3d::Identity() * 0.04, 12});
  EXPECT_EQ(node.addCentroids(a).verdict, CentroidVerdict::kAccepted);
  now += 79 * kMs;
  node.tick();
  EXPECT_TRUE(published.empty());
  now += 1 * kMs;  // epoch start + deadline
  node.tick();
  EXPECT_EQ(published, (std::vector<std::int64_t>{a.time_ns}));
  // A node without centroid input takes none.
  auto plain = tracking::Tracker::create({}, {});
  ASSERT_TRUE(plain.ok());
  TrackerNode global(std::move(*plain), 1.5, [&] { return now.load(); }, {});
  EXPECT_EQ(global.addCentroids(a).verdict, CentroidVerdict::kUnknownEdge);
  EXPECT_FALSE(global.centroidCounters().has_value());
}

using test_support::counterValue;

TEST(TrackerMetrics, CentroidFramesReceivedRejectedAndPartialEpochsAreExported) {
  Metrics metrics("", "tracker", "tracker");
  TrackerMetrics tracker_metrics(metrics, "tracker", {}, {"edge-a", "edge-b"});
  tracker_metrics.centroidsReceived("edge-a", 100);
  tracker_metrics.centroidsReceived("edge-a", 50);
  tracker_metrics.centroidsRejected("malformed");
  tracker_metrics.centroidsRejected("late");
  tracker_metrics.centroidsRejected("late");
  FusionReport report;
  report.centroids = CentroidCounters{5, 4, 2};
  tracker_metrics.fused(report);
  report.centroids = CentroidCounters{6, 5, 3};
  tracker_metrics.fused(report);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_received_total", "edge", "edge-a"), 2.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_received_total", "edge", "edge-b"), 0.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_bytes_received_total", "kind", "centroids"), 150.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_rejected_total", "reason", "malformed"), 1.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_rejected_total", "reason", "late"), 2.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_rejected_total", "reason", "duplicate"), 0.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_epochs_partial_total", "node", "tracker"), 3.0);
}

using test_support::FakeRoot;
using test_support::serveFakeRoot;

TEST(GlobalMapFeed, FollowsTheRootAcrossARestartAndSkipsMalformedMaps) {
  int port = 0;
  auto root = std::make_unique<FakeRoot>();
  auto server = serveFakeRoot(*root, port);
  ASSERT_NE(port, 0);
  std::mutex mutex;
  std::condition_variable got;
  std::vector<std::int64_t> times;
  std::atomic<int> malformed{0};
  std::atomic<int> reconnects{0};
  GlobalMapFeedHooks hooks;
  hooks.on_map = [&](const GlobalMapMessage& g, std::size_t bytes) {
    EXPECT_GT(bytes, 0U);
    std::lock_guard lock(mutex);
    times.push_back(g.header.sensor_time_ns);
    got.notify_all();
  };
  hooks.on_malformed = [&](const std::string&) { ++malformed; };
  hooks.on_reconnect = [&] { ++reconnects; };
  GlobalMapFeed feed(makeChannel("127.0.0.1:" + std::to_string(port), 4U << 20), hooks, 20ms, 100ms);
  ASSERT_TRUE(root->waitForSubscriptions(1));
  root->send(globalMapWith(1, {{1, 1, 1}}));
  {
    std::unique_lock lock(mutex);
    ASSERT_TRUE(got.wait_for(lock, 5s, [&] { return times.size() == 1; }));
  }
  // The root goes away and a new one comes up on the same port.
  root->close();
  server->Shutdown(std::chrono::system_clock::now() + 200ms);
  server.reset();
  auto second = std::make_unique<FakeRoot>();
  auto server2 = serveFakeRoot(*second, port);
  ASSERT_TRUE(server2 != nullptr);
  ASSERT_TRUE(second->waitForSubscriptions(1));
  GlobalMapMessage broken = globalMapWith(2, {{1, 1, 1}});
  broken.map.objects[0].ellipsoids[0].shape(0, 0) = -1.0;  // not positive definite
  second->send(broken);
  second->send(globalMapWith(3, {{1, 1, 1}}));
  {
    std::unique_lock lock(mutex);
    ASSERT_TRUE(got.wait_for(lock, 5s, [&] { return times.size() == 2; }));
  }
  EXPECT_EQ(times, (std::vector<std::int64_t>{1, 3}));
  EXPECT_EQ(malformed.load(), 1);
  EXPECT_GE(reconnects.load(), 1);
  // Late first publications too: the node skips only revisions.
  EXPECT_FALSE(root->askedOnTimeOnly());
  EXPECT_FALSE(second->askedOnTimeOnly());
  feed.stop();
  second->close();
  server2->Shutdown(std::chrono::system_clock::now() + 200ms);
}

}  // namespace
}  // namespace fogmap
