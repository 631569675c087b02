// The fusion tracker against hand-made cases: the paper's Algorithms 3 to 5 step by step, the
// synchronisation of asynchronous detections, and the Kalman association on crossing and
// non-crossing paths, a camera that stops, and track life cycles.
#include "common/tracking/tracker.hpp"

#include "common/perception/box_fitting.hpp"

#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <optional>
#include <random>
#include <set>

#include <gtest/gtest.h>

namespace fogmap::tracking {
namespace {

constexpr std::int64_t kMs = 1'000'000;

// A camera at `position` looking along +x of the common frame (z up): its x is -y, its y is -z.
camera::PinholeCamera forwardCamera(const std::string& name, const Eigen::Vector3d& position = {0.0, 0.0, 1.0}) {
  camera::PinholeCamera cam;
  cam.name = name;
  cam.fx = cam.fy = 500.0;
  cam.cx = 320.0;
  cam.cy = 240.0;
  cam.width = 640;
  cam.height = 480;
  Eigen::Matrix3d r;
  r << 0, -1, 0,  //
      0, 0, -1,   //
      1, 0, 0;
  cam.world_to_camera.linear() = r;
  cam.world_to_camera.translation() = -r * position;
  return cam;
}

CloudObservation at(double x, double y, double z = 0.5) {
  CloudObservation o;
  o.position = {x, y, z};
  o.covariance = Eigen::Matrix3d::Identity() * 0.01;
  return o;
}

// A detection box of +-half pixels around where `cam` sees `point`.
camera::Detection detectionOf(const camera::PinholeCamera& cam, const Eigen::Vector3d& point, const std::string& label,
                              double half = 20.0) {
  const auto pixel = cam.project(point);
  EXPECT_TRUE(pixel.has_value());
  camera::Detection d;
  d.box = {pixel->x() - half, pixel->y() - half, pixel->x() + half, pixel->y() + half};
  d.label = label;
  d.score = 1.0;
  d.camera = cam.name;
  return d;
}

CloudFrame cloudAt(std::int64_t t_ns, std::vector<CloudObservation> observations) {
  CloudFrame f;
  f.time_ns = t_ns;
  f.observations = std::move(observations);
  return f;
}

DetectionFrame detectionsAt(const std::string& camera, std::int64_t t_ns, std::vector<camera::Detection> detections) {
  return DetectionFrame{camera, t_ns, std::move(detections)};
}

Tracker makeTracker(TrackerConfig config, std::vector<camera::PinholeCamera> cameras) {
  auto tracker = Tracker::create(config, std::move(cameras));
  EXPECT_TRUE(tracker.ok()) << (tracker.ok() ? "" : tracker.error().message);
  return std::move(tracker).value();
}

const Track* trackWithLabel(const Tracker& tracker, const std::string& label) {
  for (const auto& t : tracker.tracks()) {
    if (t.label == label) return &t;
  }
  return nullptr;
}

// --- Algorithm 3 ---------------------------------------------------------------------------------

TEST(Overlay, TakesTheOverlaidObservationNearestTheSensorAndIgnoresThoseBehindOrOutside) {
  const auto cam = forwardCamera("front");
  // Two on the camera's axis (pixel (320, ~240)), 10 m and 6 m ahead; one behind; one far left.
  const std::vector<CloudObservation> observations{at(10, 0, 1), at(6, 0, 1), at(-5, 0, 1), at(5, 8, 1)};
  camera::Box2d box{300, 220, 340, 260};
  const auto g = overlay(observations, cam, box, Eigen::Vector3d::Zero());
  ASSERT_TRUE(g.has_value());
  EXPECT_EQ(*g, 1U);  // 6 m is nearer the sensor than 10 m
  // Nearest to a sensor standing beyond both: the 10 m one.
  EXPECT_EQ(*overlay(observations, cam, box, Eigen::Vector3d(12, 0, 0)), 0U);
  // A box elsewhere in the image overlays nothing; the point behind projects nowhere.
  EXPECT_FALSE(overlay(observations, cam, camera::Box2d{0, 0, 10, 10}, Eigen::Vector3d::Zero()).has_value());
  EXPECT_FALSE(overlay({at(-5, 0, 1)}, cam, camera::Box2d{0, 0, 640, 480}, Eigen::Vector3d::Zero()).has_value());
}

CloudObservation boxed(const OrientedBox& box) {
  CloudObservation o = at(box.centre.x(), box.centre.y(), box.centre.z());
  o.box = box;
  return o;
}

OrientedBox boxAt(const Eigen::Vector3d& centre, double length, double width, double height, double yaw) {
  OrientedBox b;
  b.centre = centre;
  b.length = length;
  b.width = width;
  b.height = height;
  b.yaw = yaw;
  return b;
}

TEST(OverlayByBox, ACarsDetectionLabelsTheCarBehindThePersonInFrontOfItAndThePersonsThePerson) {
  const auto cam = forwardCamera("front");
  const OrientedBox person = boxAt({8.0, 0.0, 0.9}, 0.6, 0.5, 1.8, 0.0);
  const OrientedBox car = boxAt({14.0, 0.5, 0.75}, 4.4, 1.8, 1.5, std::numbers::pi / 2.0);  // side on
  const std::vector<CloudObservation> observations{boxed(person), boxed(car)};
  const auto car_image = camera::projectPoints(cam, car.corners());
  const auto person_image = camera::projectPoints(cam, person.corners());
  ASSERT_TRUE(car_image && person_image);
  // The person's pixel lies in the car's image box: the paper's overlay takes the person (nearer).
  ASSERT_EQ(overlay(observations, cam, *car_image, Eigen::Vector3d::Zero()), std::optional<std::size_t>(0));
  EXPECT_LT(camera::iou(*person_image, *car_image), kMinOverlayIou);
  EXPECT_EQ(overlayByBox(observations, cam, *car_image, Eigen::Vector3d::Zero()), std::optional<std::size_t>(1));
  EXPECT_EQ(overlayByBox(observations, cam, *person_image, Eigen::Vector3d::Zero()), std::optional<std::size_t>(0));
  // A car the map does not hold: its detection labels nothing rather than the person.
  EXPECT_FALSE(overlayByBox({boxed(person)}, cam, *car_image, Eigen::Vector3d::Zero()).has_value());
  // Without boxes (objects off) it is the paper's overlay.
  const std::vector<CloudObservation> bare{at(8.0, 0.0, 0.9), at(14.0, 0.5, 0.75)};
  EXPECT_EQ(overlayByBox(bare, cam, *car_image, Eigen::Vector3d::Zero()), std::optional<std::size_t>(0));
}

TEST(KalmanAssociation, ACarsDetectionBehindAPersonLeavesThePersonsTrackAlone) {
  // The person walks across in front of the car; a camera sees both, but most frames only the car.
  const auto cam = forwardCamera("front");
  auto tracker = makeTracker(TrackerConfig{}, {cam});
  const OrientedBox car = boxAt({14.0, 0.5, 0.75}, 4.4, 1.8, 1.5, std::numbers::pi / 2.0);
  std::set<std::uint64_t> person_ids;
  for (int k = 0; k < 30; ++k) {
    const std::int64_t t = k * 100 * kMs;
    const OrientedBox person = boxAt({8.0, -1.5 + 0.1 * k, 0.9}, 0.6, 0.5, 1.8, 0.0);
    std::vector<camera::Detection> detections;
    camera::Detection d;
    d.box = *camera::projectPoints(cam, car.corners());
    d.label = "car";
    d.score = 0.9;
    d.camera = cam.name;
    detections.push_back(d);
    if (k % 5 == 0) {
      d.box = *camera::projectPoints(cam, person.corners());
      d.label = "person";
      detections.push_back(d);
    }
    tracker.addDetections(detectionsAt("front", t, detections));
    tracker.addCloud(cloudAt(t, {boxed(person), boxed(car)}));
    for (const auto& track : tracker.tracks()) {
      if (track.state != TrackState::kTentative && (track.position - person.centre.head<2>()).norm() < 0.5) {
        person_ids.insert(track.id);
        EXPECT_EQ(track.label, "person") << "frame " << k;
      }
    }
  }
  EXPECT_EQ(person_ids.size(), 1U);
  EXPECT_EQ(tracker.tracks().size(), 2U);
}

TEST(KalmanAssociation, ATrackWhoseObjectTurnsRoundIsRecoveredWhereItWasLastSeenNotReplaced) {
  // An object at 6 m/s that turns round on the spot: the next measurement lies 1.2 m behind the
  // prediction, beyond the gate; the track takes it by recovery and follows it back.
  TrackerConfig config;
  auto tracker = makeTracker(config, {});
  std::size_t created = 0, recovered = 0;
  double x = 0.0;
  for (int k = 0; k < 50; ++k) {
    x += k < 25 ? 0.6 : -0.6;
    const auto stats = tracker.addCloud(cloudAt(k * 100 * kMs, {at(x, 0.0)}));
    created += stats.tracks_created;
    recovered += stats.tracks_recovered;
  }
  EXPECT_EQ(created, 1U);
  EXPECT_GE(recovered, 1U) << "the gate alone kept the track: the case does not test recovery";
  ASSERT_EQ(tracker.tracks().size(), 1U);
  const Track& track = tracker.tracks()[0];
  EXPECT_EQ(track.state, TrackState::kConfirmed);
  EXPECT_NEAR(track.position.x(), x, 0.15);
  EXPECT_NEAR(track.velocity.x(), -6.0, 0.5);
  EXPECT_EQ(tracker.counters().tracks_recovered, recovered);
}

TEST(KalmanAssociation, ATrackLostForLongerThanAMomentIsNotRevivedByWhatAppearsNearIt) {
  auto tracker = makeTracker(TrackerConfig{}, {});
  // A walker at 3 m/s for 1 s, then gone for 1 s; then something 2.5 m from where it was last seen,
  // within 3 m/s x 1 s + 0.5 m but a second after the loss: a new object, not the walker.
  for (int k = 0; k < 10; ++k) tracker.addCloud(cloudAt(k * 100 * kMs, {at(0.3 * k, 0.0)}));
  ASSERT_EQ(tracker.tracks().size(), 1U);
  for (int k = 10; k < 20; ++k) tracker.addCloud(cloudAt(k * 100 * kMs, {}));
  const auto stats = tracker.addCloud(cloudAt(20 * 100 * kMs, {at(2.7 - 2.5, 0.0)}));
  EXPECT_EQ(stats.tracks_recovered, 0U);
  EXPECT_EQ(stats.tracks_created, 1U);
}

// A lost track is published for publish_lost_s after its last update, then only held: it is still
// gated (an object back on its predicted path keeps its id) and deleted after track_timeout_s.
TEST(KalmanAssociation, ALostTrackIsPublishedForPublishLostSecondsThenHeldUntilItsTimeout) {
  TrackerConfig config;
  config.publish_lost_s = 0.3;
  auto tracker = makeTracker(config, {});
  const auto published = [&] { return tracker.publishedTracks(); };
  // A walker at 1 m/s along x for 1 s, then unseen.
  for (int k = 0; k < 10; ++k) tracker.addCloud(cloudAt(k * 100 * kMs, {at(0.1 * k, 0.0)}));
  ASSERT_EQ(tracker.tracks().size(), 1U);
  const std::uint64_t walker = tracker.tracks()[0].id;
  for (int k = 10; k <= 12; ++k) {  // 0.1 to 0.3 s unseen: lost and published
    tracker.addCloud(cloudAt(k * 100 * kMs, {}));
    ASSERT_EQ(tracker.tracks()[0].state, TrackState::kLost);
    ASSERT_EQ(published().size(), 1U) << "k " << k;
  }
  tracker.addCloud(cloudAt(13 * 100 * kMs, {}));  // 0.4 s unseen
  EXPECT_EQ(tracker.tracks().size(), 1U) << "held";
  EXPECT_TRUE(published().empty()) << "not published";
  // Back on its path at 1.4 s (1.4 m): the same track, published again (confirmed again after
  // confirm_hits consecutive hits).
  tracker.addCloud(cloudAt(14 * 100 * kMs, {at(1.4, 0.0)}));
  ASSERT_EQ(published().size(), 1U);
  EXPECT_EQ(published()[0].id, walker);
  for (int k = 15; k <= 16; ++k) tracker.addCloud(cloudAt(k * 100 * kMs, {at(0.1 * k, 0.0)}));
  ASSERT_EQ(published().size(), 1U);
  EXPECT_EQ(published()[0].id, walker);
  EXPECT_EQ(published()[0].state, TrackState::kConfirmed);
  // Unseen for good after 1.6 s: published for 0.3 s, held until the 2 s timeout, then gone.
  for (int k = 17; k <= 36; ++k) {
    tracker.addCloud(cloudAt(k * 100 * kMs, {}));
    EXPECT_EQ(published().size(), k <= 19 ? 1U : 0U) << "k " << k;
    EXPECT_EQ(tracker.tracks().size(), 1U) << "k " << k;
  }
  tracker.addCloud(cloudAt(37 * 100 * kMs, {}));
  EXPECT_TRUE(tracker.tracks().empty());
  // The window is within [0, track_timeout_s].
  config.publish_lost_s = config.track_timeout_s + 0.1;
  EXPECT_FALSE(validate(config));
  config.publish_lost_s = -0.1;
  EXPECT_FALSE(validate(config));
  config.publish_lost_s = 0.0;
  EXPECT_TRUE(validate(config));
}

TEST(KalmanAssociation, RecoveryReachesNoFurtherThanTheTracksSpeedAllowsAndTakesNoTentativeTrack) {
  auto tracker = makeTracker(TrackerConfig{}, {});
  // A person standing still for a second, then gone; something appears 2 m away.
  for (int k = 0; k < 10; ++k) tracker.addCloud(cloudAt(k * 100 * kMs, {at(5.0, 0.0)}));
  ASSERT_EQ(tracker.tracks().size(), 1U);
  const std::uint64_t standing = tracker.tracks()[0].id;
  const auto stats = tracker.addCloud(cloudAt(10 * 100 * kMs, {at(7.0, 0.0)}));
  EXPECT_EQ(stats.tracks_recovered, 0U);
  EXPECT_EQ(stats.tracks_created, 1U);
  ASSERT_EQ(tracker.tracks().size(), 2U);
  EXPECT_EQ(tracker.tracks()[0].id, standing);
  EXPECT_EQ(tracker.tracks()[0].state, TrackState::kLost);
}

// --- Algorithms 2, 4 and 5 (association: paper) --------------------------------------------------

TrackerConfig paperConfig() {
  TrackerConfig c;
  c.association = Association::kPaper;
  c.rho_overlay_m = 0.5;
  c.rho_purecloud_m = 0.3;
  return c;
}

TEST(PaperAssociation, FusionCreatesALabelledTrackAndUpdatesItWithinRhoOverlay) {
  const auto cam = forwardCamera("front");
  auto tracker = makeTracker(paperConfig(), {cam});
  tracker.addDetections(detectionsAt("front", 0, {detectionOf(cam, {8, 0, 1}, "person")}));
  auto stats = tracker.addCloud(cloudAt(0, {at(8, 0, 1)}));
  EXPECT_EQ(stats.detections_fused, 1U);
  EXPECT_EQ(stats.tracks_created, 1U);
  ASSERT_EQ(tracker.tracks().size(), 1U);
  const auto id = tracker.tracks()[0].id;
  EXPECT_EQ(tracker.tracks()[0].label, "person");
  EXPECT_TRUE(tracker.tracks()[0].camera_confirmed);

  // 0.4 m further: within rho_overlay, same label: the same track, at the new position.
  tracker.addDetections(detectionsAt("front", 100 * kMs, {detectionOf(cam, {8.4, 0, 1}, "person")}));
  stats = tracker.addCloud(cloudAt(100 * kMs, {at(8.4, 0, 1)}));
  EXPECT_EQ(stats.updates_overlay, 1U);
  EXPECT_EQ(stats.tracks_created, 0U);
  ASSERT_EQ(tracker.tracks().size(), 1U);
  EXPECT_EQ(tracker.tracks()[0].id, id);
  EXPECT_DOUBLE_EQ(tracker.tracks()[0].position.x(), 8.4);

  // 0.6 m further: beyond rho_overlay: the paper makes a new track (and keeps the old one).
  tracker.addDetections(detectionsAt("front", 200 * kMs, {detectionOf(cam, {9.0, 0, 1}, "person")}));
  stats = tracker.addCloud(cloudAt(200 * kMs, {at(9.0, 0, 1)}));
  EXPECT_EQ(stats.tracks_created, 1U);
  EXPECT_EQ(tracker.tracks().size(), 2U);
}

TEST(PaperAssociation, AnotherLabelMakesANewTrackEvenAtTheSamePlace) {
  const auto cam = forwardCamera("front");
  auto tracker = makeTracker(paperConfig(), {cam});
  tracker.addDetections(detectionsAt("front", 0, {detectionOf(cam, {8, 0, 1}, "person")}));
  tracker.addCloud(cloudAt(0, {at(8, 0, 1)}));
  tracker.addDetections(detectionsAt("front", 100 * kMs, {detectionOf(cam, {8, 0, 1}, "car")}));
  const auto stats = tracker.addCloud(cloudAt(100 * kMs, {at(8, 0, 1)}));
  EXPECT_EQ(stats.tracks_created, 1U);
  EXPECT_EQ(stats.updates_overlay, 0U);
  ASSERT_NE(trackWithLabel(tracker, "car"), nullptr);
  ASSERT_NE(trackWithLabel(tracker, "person"), nullptr);
}

TEST(PaperAssociation, ATrackWithoutDetectionTakesTheNearestCentroidWithinRhoPurecloudOnly) {
  const auto cam = forwardCamera("front");
  auto tracker = makeTracker(paperConfig(), {cam});
  tracker.addDetections(detectionsAt("front", 0, {detectionOf(cam, {8, 0, 1}, "person")}));
  tracker.addCloud(cloudAt(0, {at(8, 0, 1)}));
  // No detection: centroids 0.2 m and 0.25 m away: the nearest one (0.2 m) is taken.
  auto stats = tracker.addCloud(cloudAt(100 * kMs, {at(8.25, 0, 1), at(8.2, 0, 1)}));
  EXPECT_EQ(stats.updates_cloud_only, 1U);
  EXPECT_DOUBLE_EQ(tracker.tracks()[0].position.x(), 8.2);
  // 0.35 m away: beyond rho_purecloud: the track stays where it was, and no track is made.
  stats = tracker.addCloud(cloudAt(200 * kMs, {at(8.55, 0, 1)}));
  EXPECT_EQ(stats.updates_cloud_only, 0U);
  EXPECT_EQ(stats.tracks_created, 0U);
  EXPECT_DOUBLE_EQ(tracker.tracks()[0].position.x(), 8.2);
  EXPECT_EQ(tracker.tracks()[0].state, TrackState::kLost);
}

TEST(PaperAssociation, CentroidsAloneNeverCreateTracks) {
  auto tracker = makeTracker(paperConfig(), {forwardCamera("front")});
  for (int k = 0; k < 10; ++k) tracker.addCloud(cloudAt(k * 100 * kMs, {at(8, 0, 1), at(12, 3, 1)}));
  EXPECT_TRUE(tracker.tracks().empty());
}

// --- Synchronisation (Algorithm 2's input) ---------------------------------------------------------

TEST(FusionSync, TheDetectionFrameNearestInTimeWithinEpsSyncIsFusedAndOlderOnesAreDroppedAsStale) {
  const auto cam = forwardCamera("front");
  TrackerConfig config = paperConfig();
  config.eps_sync_s = 0.1;
  auto tracker = makeTracker(config, {cam});
  // Three frames of the same camera around a LiDAR frame at 1 s: 0.85 s (outside), 0.95 s and
  // 1.02 s (inside; 1.02 is nearer). Only the 1.02 s frame (a "car") may be fused.
  tracker.addDetections(detectionsAt("front", 850 * kMs, {detectionOf(cam, {8, 0, 1}, "bus")}));
  tracker.addDetections(detectionsAt("front", 950 * kMs, {detectionOf(cam, {8, 0, 1}, "truck")}));
  tracker.addDetections(detectionsAt("front", 1020 * kMs, {detectionOf(cam, {8, 0, 1}, "car")}));
  const auto stats = tracker.addCloud(cloudAt(1000 * kMs, {at(8, 0, 1)}));
  EXPECT_EQ(stats.detection_frames_used, 1U);
  ASSERT_EQ(tracker.tracks().size(), 1U);
  EXPECT_EQ(tracker.tracks()[0].label, "car");
  EXPECT_EQ(tracker.counters().detection_frames_stale, 1U);  // 0.85 s can match no later LiDAR frame
  // 0.95 s is still within eps of a LiDAR frame at 1.05 s: it waits. A frame older than the last
  // LiDAR frame by more than eps is dropped on arrival.
  tracker.addDetections(detectionsAt("front", 880 * kMs, {}));
  EXPECT_EQ(tracker.counters().detection_frames_stale, 2U);
  // The next LiDAR frame at 1.2 s: 0.95 s is now more than eps older: stale, never fused.
  const auto later = tracker.addCloud(cloudAt(1200 * kMs, {at(8, 0, 1)}));
  EXPECT_EQ(later.detection_frames_used, 0U);
  EXPECT_EQ(later.detections_fused, 0U);
  EXPECT_EQ(tracker.counters().detection_frames_stale, 3U);
}

TEST(FusionSync, UnknownCamerasOverflowAndOutOfOrderLidarFramesAreCountedNeverFused) {
  const auto cam = forwardCamera("front");
  TrackerConfig config = paperConfig();
  config.max_buffered_frames = 2;
  auto tracker = makeTracker(config, {cam});
  tracker.addDetections(detectionsAt("rear", 0, {detectionOf(cam, {8, 0, 1}, "person")}));
  EXPECT_EQ(tracker.counters().detection_frames_unknown_camera, 1U);
  for (int k = 0; k < 3; ++k) tracker.addDetections(detectionsAt("front", k * 10 * kMs, {}));
  EXPECT_EQ(tracker.counters().detection_frames_overflow, 1U);
  tracker.addCloud(cloudAt(500 * kMs, {}));
  const auto stats = tracker.addCloud(cloudAt(400 * kMs, {at(8, 0, 1)}));
  EXPECT_EQ(tracker.counters().cloud_frames_out_of_order, 1U);
  EXPECT_EQ(stats.tracks_created, 0U);
  EXPECT_EQ(tracker.lastCapture().at("front"), 20 * kMs);
}

TEST(TrackerConfig, EveryBadFieldIsRefusedByName) {
  const auto refused = [](TrackerConfig c, const std::string& field) {
    const auto t = Tracker::create(c, {});
    ASSERT_FALSE(t.ok()) << field;
    EXPECT_NE(t.error().message.find(field), std::string::npos) << t.error().message;
  };
  TrackerConfig c;
  c.eps_sync_s = 0.0;
  refused(c, "eps_sync_s");
  c = {};
  c.gate_chi2 = std::nan("");
  refused(c, "gate_chi2");
  c = {};
  c.confirm_hits = 0;
  refused(c, "confirm_hits");
  c = {};
  c.track_timeout_s = -1;
  refused(c, "track_timeout_s");
  auto twice = Tracker::create({}, {forwardCamera("a"), forwardCamera("a")});
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.error().message.find("'a' is listed twice"), std::string::npos);
  auto bad_camera = forwardCamera("b");
  bad_camera.fx = 0.0;
  EXPECT_FALSE(Tracker::create({}, {bad_camera}).ok());
  EXPECT_FALSE(parseAssociation("greedy").ok());
  EXPECT_EQ(*parseAssociation("paper"), Association::kPaper);
}

// --- association: kalman ---------------------------------------------------------------------------

struct Walker {
  Eigen::Vector2d start;
  Eigen::Vector2d velocity;
  Eigen::Vector2d at(double t) const { return start + velocity * t; }
};

// Runs walkers for `frames` LiDAR frames at 10 Hz with camera detections on the frames
// `with_camera` allows; returns, per walker, the set of track ids that covered it (a track covers
// a walker when it is the nearest confirmed track within 1 m, on frames where no other walker is
// within 1 m).
std::vector<std::set<std::uint64_t>> run(Tracker& tracker, const camera::PinholeCamera& cam, const std::vector<Walker>& walkers,
                                         int frames, const std::function<bool(int)>& with_camera, int warmup = 3) {
  std::vector<std::set<std::uint64_t>> ids(walkers.size());
  for (int k = 0; k < frames; ++k) {
    const double t = 0.1 * k;
    const std::int64_t t_ns = k * 100 * kMs;
    std::vector<CloudObservation> observations;
    std::vector<camera::Detection> detections;
    for (const auto& w : walkers) {
      const Eigen::Vector2d p = w.at(t);
      observations.push_back(at(p.x(), p.y(), 0.9));
      if (with_camera(k)) detections.push_back(detectionOf(cam, {p.x(), p.y(), 0.9}, "person", 8.0));
    }
    if (with_camera(k)) tracker.addDetections(detectionsAt(cam.name, t_ns + 30 * kMs, detections));  // 30 ms late
    tracker.addCloud(cloudAt(t_ns, observations));
    if (k < warmup) continue;
    for (std::size_t w = 0; w < walkers.size(); ++w) {
      // Where two walkers stand within a metre of each other, which track is whose is not defined.
      bool crowded = false;
      for (std::size_t v = 0; v < walkers.size(); ++v) crowded |= v != w && (walkers[v].at(t) - walkers[w].at(t)).norm() < 1.0;
      if (crowded) continue;
      const Track* best = nullptr;
      for (const auto& track : tracker.tracks()) {
        if (track.state == TrackState::kTentative) continue;
        const double d = (track.position - walkers[w].at(t)).norm();
        if (d < 1.0 && (!best || d < (best->position - walkers[w].at(t)).norm())) best = &track;
      }
      if (best) ids[w].insert(best->id);
    }
  }
  return ids;
}

TEST(KalmanAssociation, CrossingWalkersKeepTheirIdsAfterMeetingAtOnePoint) {
  const auto cam = forwardCamera("front", {-5.0, 0.0, 1.0});
  auto tracker = makeTracker(TrackerConfig{}, {cam});
  // Two people crossing in an X at 1.4 m/s, meeting at (10, 0) at t = 2 s.
  const std::vector<Walker> walkers{{{8.0, -2.0}, {1.0, 1.0}}, {{8.0, 2.0}, {1.0, -1.0}}};
  const auto ids = run(tracker, cam, walkers, 40, [](int) { return true; });
  ASSERT_EQ(ids[0].size(), 1U);
  ASSERT_EQ(ids[1].size(), 1U);
  EXPECT_NE(*ids[0].begin(), *ids[1].begin());
  for (const auto& track : tracker.tracks()) {
    EXPECT_EQ(track.label, "person");
    EXPECT_NEAR(track.velocity.x(), 1.0, 0.1);  // the filter has learnt the motion
  }
}

TEST(KalmanAssociation, ParallelWalkersOneMetreApartNeverSwap) {
  const auto cam = forwardCamera("front", {-5.0, 0.0, 1.0});
  auto tracker = makeTracker(TrackerConfig{}, {cam});
  const std::vector<Walker> walkers{{{6.0, -0.5}, {1.2, 0.0}}, {{6.0, 0.5}, {1.2, 0.0}}, {{14.0, 3.0}, {-1.0, 0.0}}};
  const auto ids = run(tracker, cam, walkers, 50, [](int) { return true; });
  std::set<std::uint64_t> all;
  for (const auto& s : ids) {
    ASSERT_EQ(s.size(), 1U);
    all.insert(*s.begin());
  }
  EXPECT_EQ(all.size(), 3U);
}

TEST(KalmanAssociation, TracksSurviveACameraThatStopsForTwoSecondsAndKeepTheirLabels) {
  const auto cam = forwardCamera("front", {-5.0, 0.0, 1.0});
  auto tracker = makeTracker(TrackerConfig{}, {cam});
  const std::vector<Walker> walkers{{{6.0, -2.0}, {1.0, 0.2}}, {{12.0, 2.0}, {-0.5, -0.2}}};
  // The camera sends frames 0..9, nothing for 2 s (frames 10..29), then again.
  const auto camera_on = [](int k) { return k < 10 || k >= 30; };
  const auto ids = run(tracker, cam, walkers, 40, camera_on);
  for (const auto& s : ids) EXPECT_EQ(s.size(), 1U);
  EXPECT_GT(tracker.counters().updates_cloud_only, 30U);  // 2 walkers x 20 frames without a camera
  for (const auto& track : tracker.tracks()) {
    EXPECT_EQ(track.label, "person");
    EXPECT_EQ(track.state, TrackState::kConfirmed);
  }
}

TEST(KalmanAssociation, LidarAloneConfirmsAfterConfirmHitsWithAnUnknownLabelThatACameraLaterNames) {
  const auto cam = forwardCamera("front");
  TrackerConfig config;
  config.confirm_hits = 3;
  auto tracker = makeTracker(config, {cam});
  tracker.addCloud(cloudAt(0, {at(8, 0, 1)}));
  ASSERT_EQ(tracker.tracks().size(), 1U);
  EXPECT_EQ(tracker.tracks()[0].state, TrackState::kTentative);
  tracker.addCloud(cloudAt(100 * kMs, {at(8, 0, 1)}));
  EXPECT_EQ(tracker.tracks()[0].state, TrackState::kTentative);
  tracker.addCloud(cloudAt(200 * kMs, {at(8, 0, 1)}));
  EXPECT_EQ(tracker.tracks()[0].state, TrackState::kConfirmed);
  EXPECT_EQ(tracker.tracks()[0].label, kUnknownLabel);
  EXPECT_FALSE(tracker.tracks()[0].camera_confirmed);
  const auto id = tracker.tracks()[0].id;
  tracker.addDetections(detectionsAt("front", 300 * kMs, {detectionOf(cam, {8, 0, 1}, "person")}));
  tracker.addCloud(cloudAt(300 * kMs, {at(8, 0, 1)}));
  ASSERT_EQ(tracker.tracks().size(), 1U);
  EXPECT_EQ(tracker.tracks()[0].id, id);
  EXPECT_EQ(tracker.tracks()[0].label, "person");
  EXPECT_TRUE(tracker.tracks()[0].camera_confirmed);
}

CloudObservation classed(double x, double y, ObjectClass object_class, double confidence) {
  CloudObservation o = at(x, y, 0.9);
  o.lidar_class = ObjectLabel{object_class, confidence};
  return o;
}

TEST(KalmanAssociation, WithoutCamerasTheLidarClassLabelsTheTrackAndACameraOutvotesAFewFrames) {
  TrackerConfig config;
  config.confirm_hits = 3;
  auto lidar_only = makeTracker(config, {});
  for (int k = 0; k < 5; ++k) lidar_only.addCloud(cloudAt(k * 100 * kMs, {classed(8.0 + 0.1 * k, 0, ObjectClass::kCar, 0.9)}));
  ASSERT_EQ(lidar_only.tracks().size(), 1U);
  EXPECT_EQ(lidar_only.tracks()[0].state, TrackState::kConfirmed);
  EXPECT_EQ(lidar_only.tracks()[0].label, "car");
  EXPECT_FALSE(lidar_only.tracks()[0].camera_confirmed);

  // One frame's LiDAR vote weighs 0.5 x 0.9 = 0.45; a camera detection of score 0.8 outweighs it,
  // and a second LiDAR frame (0.9 in all) outweighs the camera again.
  const auto cam = forwardCamera("front");
  auto fused = makeTracker(config, {cam});
  fused.addCloud(cloudAt(0, {classed(8, 0, ObjectClass::kCar, 0.9)}));
  EXPECT_EQ(fused.tracks()[0].label, "car");
  camera::Detection seen = detectionOf(cam, {8, 0, 0.9}, "person");
  seen.score = 0.8;
  fused.addDetections(detectionsAt("front", 100 * kMs, {seen}));
  fused.addCloud(cloudAt(100 * kMs, {at(8, 0, 0.9)}));
  EXPECT_EQ(fused.tracks()[0].label, "person");
  fused.addCloud(cloudAt(200 * kMs, {classed(8, 0, ObjectClass::kCar, 0.9)}));
  EXPECT_EQ(fused.tracks()[0].label, "car");

  // Weight 0: LiDAR classes never label a track.
  config.lidar_class_weight = 0.0;
  auto unlabelled = makeTracker(config, {});
  for (int k = 0; k < 4; ++k) unlabelled.addCloud(cloudAt(k * 100 * kMs, {classed(8, 0, ObjectClass::kCar, 1.0)}));
  EXPECT_EQ(unlabelled.tracks()[0].label, kUnknownLabel);
  config.lidar_class_weight = 11.0;
  EXPECT_FALSE(validate(config));
}

// A car 4.4 x 1.8 m driving along +x at 5 m/s, seen from far behind on its left: its rear face and
// the rear 2 m of its left side (the rest hidden). As the tracker node measures it without a
// heading, the 2 m side reads as a rear face's width and the car as turned across: 1.8 m off.
CloudObservation rearLeftView(double centre_x) {
  OrientedBox seen;
  seen.centre = Eigen::Vector3d(centre_x - 1.2, 0.0, 0.7);
  seen.length = 2.0;
  seen.width = 1.8;
  seen.yaw = 0.0;
  seen.anchor = BoxAnchor::kRearLeft;
  CloudObservation o = at(0, 0, 0.7);
  o.box = seen;
  o.lidar_class = ObjectLabel{ObjectClass::kCar, 0.9};
  o.position.head<2>() = grownFromAnchor(seen, *vehiclePrior(ObjectClass::kCar)).centre.head<2>();
  o.covariance = Eigen::Vector3d(0.09, 0.09, 0.09).asDiagonal();
  return o;
}

TEST(KalmanAssociation, AMovingCarIsUpdatedOnItsBoxGrownAlongItsMotionAndKeepsOneTrack) {
  const CloudObservation first = rearLeftView(10.0);
  ASSERT_GT((first.position.head<2>() - Eigen::Vector2d(10.0, 0.0)).norm(), 1.5) << "the guess without motion is off";
  auto tracker = makeTracker(TrackerConfig{}, {});
  std::set<std::uint64_t> ids;
  for (int k = 0; k < 40; ++k) {
    const double x = 10.0 + 0.5 * k;  // 5 m/s at 10 Hz
    tracker.addCloud(cloudAt(k * 100 * kMs, {rearLeftView(x)}));
    for (const auto& track : tracker.tracks()) {
      if (track.state != TrackState::kTentative) ids.insert(track.id);
    }
    if (k == 39) {
      ASSERT_EQ(tracker.tracks().size(), 1U);
      const Track& car = tracker.tracks()[0];
      EXPECT_LT((car.position - Eigen::Vector2d(x, 0.0)).norm(), 0.15) << car.position.transpose() << " at " << x;
      EXPECT_NEAR(car.velocity.x(), 5.0, 0.2);
      EXPECT_EQ(car.label, "car");
    }
  }
  EXPECT_EQ(ids.size(), 1U);
}

TEST(KalmanAssociation, UnobservedTracksAreLostThenDeletedAfterTheTimeoutAndTentativeOnesSooner) {
  const auto cam = forwardCamera("front");
  TrackerConfig config;
  config.track_timeout_s = 1.0;
  config.tentative_timeout_s = 0.25;
  auto tracker = makeTracker(config, {cam});
  tracker.addDetections(detectionsAt("front", 0, {detectionOf(cam, {8, 0, 1}, "person")}));
  tracker.addCloud(cloudAt(0, {at(8, 0, 1), at(20, 5, 1)}));  // a person, and a LiDAR-only blob
  ASSERT_EQ(tracker.tracks().size(), 2U);
  std::size_t deleted = 0;
  std::vector<std::pair<int, std::size_t>> sizes;
  for (int k = 1; k <= 12; ++k) {
    const auto stats = tracker.addCloud(cloudAt(k * 100 * kMs, {}));
    deleted += stats.tracks_deleted;
    sizes.emplace_back(k, tracker.tracks().size());
    if (k == 1) {
      ASSERT_EQ(tracker.tracks().size(), 2U);
      EXPECT_EQ(trackWithLabel(tracker, "person")->state, TrackState::kLost);
    }
  }
  // The blob goes at 0.3 s (> 0.25 s unobserved), the person at 1.1 s (> 1 s).
  EXPECT_EQ(sizes[1].second, 2U);   // 0.2 s
  EXPECT_EQ(sizes[2].second, 1U);   // 0.3 s
  EXPECT_EQ(sizes[9].second, 1U);   // 1.0 s
  EXPECT_EQ(sizes[10].second, 0U);  // 1.1 s
  EXPECT_EQ(deleted, 2U);
  EXPECT_EQ(tracker.counters().tracks_deleted, 2U);
}

TEST(KalmanAssociation, TwoCamerasSeeingOneObjectMakeOneTrackWhereThePaperMakesTwo) {
  const auto front = forwardCamera("front", {-5.0, -1.0, 1.0});
  const auto second = forwardCamera("second", {-5.0, 1.0, 1.0});
  for (const auto association : {Association::kKalman, Association::kPaper}) {
    TrackerConfig config;
    config.association = association;
    auto tracker = makeTracker(config, {front, second});
    tracker.addDetections(detectionsAt("front", 0, {detectionOf(front, {8, 0, 1}, "person")}));
    tracker.addDetections(detectionsAt("second", 0, {detectionOf(second, {8, 0, 1}, "person")}));
    const auto stats = tracker.addCloud(cloudAt(0, {at(8, 0, 1)}));
    EXPECT_EQ(stats.detections_fused, 2U);
    EXPECT_EQ(tracker.tracks().size(), association == Association::kKalman ? 1U : 2U) << associationName(association);
  }
}

// --- asynchronous fusion ---------------------------------------------------------------------------

TEST(AsynchronousFusion, ALidarFrameWaitsForTheDetectionsThatArriveAfterItThenFusesThem) {
  const auto front = forwardCamera("front");
  const auto side = forwardCamera("side", {0.0, 0.5, 1.0});
  TrackerConfig config;
  config.max_detection_wait_s = 0.25;
  auto tracker = makeTracker(config, {front, side});
  // The LiDAR frame at 1 s comes first (LiDAR processing is faster than detection).
  EXPECT_TRUE(tracker.offerCloud(cloudAt(1000 * kMs, {at(8, 0, 1)}), 1005 * kMs).empty());
  EXPECT_EQ(tracker.waitingClouds(), 1U);
  // 60 ms later the front camera's frame of the same instant arrives: the side camera is still due.
  tracker.addDetections(detectionsAt("front", 1000 * kMs, {detectionOf(front, {8, 0, 1}, "person")}));
  EXPECT_TRUE(tracker.advance(1060 * kMs).empty());
  // The side camera's frame captured after the LiDAR frame: every camera has spoken, fuse.
  tracker.addDetections(detectionsAt("side", 1010 * kMs, {detectionOf(side, {8, 0, 1}, "person")}));
  const auto fused = tracker.advance(1080 * kMs);
  ASSERT_EQ(fused.size(), 1U);
  EXPECT_EQ(fused[0].time_ns, 1000 * kMs);
  EXPECT_EQ(fused[0].detections_fused, 2U);
  ASSERT_EQ(tracker.tracks().size(), 1U);
  EXPECT_EQ(tracker.tracks()[0].label, "person");
  EXPECT_EQ(tracker.counters().detection_frames_stale, 0U);
}

TEST(AsynchronousFusion, ACameraThatStaysSilentDelaysFusionByAtMostTheWaitAndOrderIsKept) {
  const auto front = forwardCamera("front");
  TrackerConfig config;
  config.max_detection_wait_s = 0.25;
  auto tracker = makeTracker(config, {front});
  EXPECT_TRUE(tracker.offerCloud(cloudAt(1000 * kMs, {at(8, 0, 1)}), 1000 * kMs).empty());
  EXPECT_TRUE(tracker.offerCloud(cloudAt(1100 * kMs, {at(8.1, 0, 1)}), 1100 * kMs).empty());
  EXPECT_TRUE(tracker.advance(1249 * kMs).empty());
  auto fused = tracker.advance(1250 * kMs);  // the first frame's wait is over, the second's not
  ASSERT_EQ(fused.size(), 1U);
  EXPECT_EQ(fused[0].time_ns, 1000 * kMs);
  fused = tracker.advance(1400 * kMs);
  ASSERT_EQ(fused.size(), 1U);
  EXPECT_EQ(fused[0].time_ns, 1100 * kMs);
  // A frame older than one already offered is out of order: dropped and counted.
  EXPECT_TRUE(tracker.offerCloud(cloudAt(1050 * kMs, {}), 1400 * kMs).empty());
  EXPECT_EQ(tracker.counters().cloud_frames_out_of_order, 1U);
  EXPECT_EQ(tracker.waitingClouds(), 0U);
}

TEST(AsynchronousFusion, WithoutWaitingLateDetectionsAreStaleWhichIsWhyTheWaitExists) {
  const auto front = forwardCamera("front");
  TrackerConfig config;
  config.max_detection_wait_s = 0.0;
  auto tracker = makeTracker(config, {front});
  for (int k = 0; k < 5; ++k) {
    const std::int64_t t = 1000 * kMs + k * 100 * kMs;
    tracker.offerCloud(cloudAt(t, {at(8, 0, 1)}), t + 5 * kMs);
    // Each frame's detections come 20 ms after it, after the LiDAR frame was fused.
    tracker.addDetections(detectionsAt("front", t, {detectionOf(front, {8, 0, 1}, "person")}));
  }
  EXPECT_EQ(tracker.counters().detections_fused, 0U);
  EXPECT_GE(tracker.counters().detection_frames_stale, 3U);
}

// --- Load shedding ------------------------------------------------------------------------------

CloudObservation withPoints(CloudObservation o, std::size_t points) {
  o.point_count = points;
  return o;
}

const Track* trackNear(const Tracker& tracker, const Eigen::Vector2d& p, double within_m) {
  const Track* best = nullptr;
  for (const auto& t : tracker.tracks()) {
    if ((t.position - p).norm() <= within_m && (!best || (t.position - p).norm() < (best->position - p).norm())) best = &t;
  }
  return best;
}

TEST(LoadShedding, OverBudgetEachTrackKeepsItsNearestObservationAndTheRestGoByPoints) {
  TrackerConfig config;
  config.confirm_hits = 1;  // every observation a confirmed track at once
  auto tracker = makeTracker(config, {});
  tracker.addCloud(cloudAt(1000 * kMs, {withPoints(at(0, 0), 10), withPoints(at(10, 0), 10)}));
  ASSERT_EQ(tracker.tracks().size(), 2U);
  tracker.setMeasurementBudget(3);
  // Each track's nearest (few points), one with many points near the first track, and three far
  // ones; the budget takes the two nearest and then the one with the most points of the rest.
  const auto stats = tracker.addCloud(cloudAt(1100 * kMs, {withPoints(at(30, 0), 50), withPoints(at(0.1, 0), 5),
                                                           withPoints(at(0.9, 0), 100), withPoints(at(40, 0), 80),
                                                           withPoints(at(10.2, 0), 5), withPoints(at(50, 0), 10)}));
  EXPECT_EQ(stats.measurements, 3U);
  EXPECT_EQ(stats.measurements_shed, 3U);
  EXPECT_EQ(tracker.counters().measurements_shed, 3U);
  EXPECT_EQ(stats.updates_cloud_only, 2U) << "both tracks updated by their nearest";
  EXPECT_EQ(stats.tracks_created, 1U) << "the one with the most points starts a track";
  EXPECT_NE(trackNear(tracker, {0.9, 0}, 0.05), nullptr);
  for (const double x : {30.0, 40.0, 50.0}) EXPECT_EQ(trackNear(tracker, {x, 0}, 1.0), nullptr) << "shed: " << x;
  // Within the budget (and with none), nothing is shed.
  tracker.setMeasurementBudget(6);
  const auto all = tracker.addCloud(cloudAt(1200 * kMs, {at(0.1, 0), at(10.2, 0), at(30, 0), at(40, 0), at(50, 0), at(60, 0)}));
  EXPECT_EQ(all.measurements, 6U);
  EXPECT_EQ(all.measurements_shed, 0U);
  EXPECT_EQ(tracker.counters().measurements_shed, 3U);
}

TEST(LoadShedding, PeopleKeepTheirTrackIdsThroughAFloodOfClutterWithMorePoints) {
  // 6 people walking at 1 m/s; after 10 frames, every frame also brings 1,000 clutter observations
  // at new random places, each claiming 20 times a person's points. The budget is 64 a step.
  auto tracker = makeTracker({}, {});
  const auto person = [](int i, int frame) {
    return Eigen::Vector2d(3.0 * i, -5.0 + 0.1 * frame * (i % 2 == 0 ? 1.0 : -1.0) + 0.5 * i);
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(20.0, 120.0);
  std::uniform_real_distribution<double> y(-50.0, 50.0);
  std::map<int, std::uint64_t> ids;  // per person, its track's id once confirmed
  std::uint64_t shed = 0;
  for (int frame = 0; frame < 50; ++frame) {
    std::vector<CloudObservation> observations;
    for (int i = 0; i < 6; ++i) observations.push_back(withPoints(at(person(i, frame).x(), person(i, frame).y()), 50));
    if (frame >= 10) {
      tracker.setMeasurementBudget(64);
      for (int j = 0; j < 1000; ++j) observations.push_back(withPoints(at(x(rng), y(rng)), 1000));
    }
    const auto stats = tracker.addCloud(cloudAt(1000 * kMs + frame * 100 * kMs, observations));
    shed += stats.measurements_shed;
    if (frame < 5) continue;  // confirmed after 3 hits
    for (int i = 0; i < 6; ++i) {
      const Track* t = trackNear(tracker, person(i, frame), 0.5);
      ASSERT_NE(t, nullptr) << "person " << i << ", frame " << frame;
      EXPECT_EQ(t->state, TrackState::kConfirmed) << "person " << i << ", frame " << frame;
      if (frame == 5) ids[i] = t->id;
      EXPECT_EQ(t->id, ids[i]) << "person " << i << " changed track at frame " << frame;
    }
  }
  EXPECT_EQ(shed, 40U * (1006U - 64U));
  EXPECT_EQ(tracker.counters().measurements_shed, shed);
}

// A vehicle track's heading (vehicleHeading): its box's axis, turned to the track's motion, or to
// its previous heading when it stands; the motion itself when the axis is across it.
TEST(VehicleHeading, TheBoxAxisPointsTheWayTheTrackMovesOrKeepsItsLastDirection) {
  CloudObservation car;
  car.box = OrientedBox{Eigen::Vector3d(10, 0, 0.8), 4.4, 1.8, 1.5, 0.1};
  car.lidar_class = ObjectLabel{ObjectClass::kCar, 0.9};
  const double pi = std::numbers::pi;
  // Moving along +x and along -x: the axis, or the axis turned by pi.
  EXPECT_NEAR(*vehicleHeading(car, {5.0, 0.0}, std::nullopt), 0.1, 1e-12);
  EXPECT_NEAR(*vehicleHeading(car, {-5.0, 0.0}, std::nullopt), 0.1 - pi, 1e-12);
  // Too slow to say (below kHeadingMinSpeedMps): the direction nearer the previous heading; without
  // one, none (a standing car's front is not known from its box).
  EXPECT_NEAR(*vehicleHeading(car, {0.2, 0.0}, 3.0), 0.1 - pi, 1e-12);
  EXPECT_FALSE(vehicleHeading(car, {0.2, 0.0}, std::nullopt).has_value());
  // An axis across the motion (more than 45 degrees off: a car seen end-on): the motion's direction.
  car.box->yaw = -pi / 2.0 + 0.2;
  EXPECT_NEAR(*vehicleHeading(car, {0.0, -4.0}, std::nullopt), -pi / 2.0 + 0.2, 1e-12) << "within 45 degrees: the axis";
  EXPECT_NEAR(*vehicleHeading(car, {4.0, 0.0}, std::nullopt), 0.0, 1e-12) << "across: the motion";
  // No box: the previous heading stays, whatever it was; a box no vehicle's (a person's) clears it.
  CloudObservation person;
  person.box = OrientedBox{Eigen::Vector3d(3, 0, 0.9), 0.6, 0.5, 1.8, 0.0};
  person.lidar_class = ObjectLabel{ObjectClass::kPerson, 0.8};
  EXPECT_FALSE(vehicleHeading(person, {3.0, 0.0}, std::nullopt).has_value());
  EXPECT_FALSE(vehicleHeading(person, {3.0, 0.0}, 1.25).has_value());
  EXPECT_EQ(vehicleHeading(CloudObservation{}, {3.0, 0.0}, 1.25), std::optional<double>(1.25));
}

// Through the tracker: a car driving along -x with its box seen every frame gets a track whose
// heading points along -x; a person's track has none.
TEST(VehicleHeading, ACarsTrackCarriesItsHeadingAndAPersonsNone) {
  auto tracker = makeTracker(TrackerConfig{}, {});
  const double pi = std::numbers::pi;
  for (int f = 0; f < 20; ++f) {
    const double t = 0.1 * f;
    CloudFrame frame;
    frame.time_ns = static_cast<std::int64_t>(std::llround(t * 1e9));
    CloudObservation car;
    car.position = {30.0 - 8.0 * t, 0.0, 0.8};
    car.box = OrientedBox{car.position, 4.4, 1.8, 1.5, 0.02};
    car.lidar_class = ObjectLabel{ObjectClass::kCar, 0.9};
    car.point_count = 200;
    CloudObservation person;
    person.position = {0.0, 10.0 + 1.2 * t, 0.9};
    person.box = OrientedBox{person.position, 0.6, 0.5, 1.8, 0.3};
    person.lidar_class = ObjectLabel{ObjectClass::kPerson, 0.8};
    person.point_count = 40;
    frame.observations = {car, person};
    tracker.addCloud(frame);
  }
  ASSERT_EQ(tracker.tracks().size(), 2U);
  for (const Track& track : tracker.tracks()) {
    if (track.position.x() > 5.0) {
      ASSERT_TRUE(track.heading_rad.has_value());
      // Along -x: between the box's axis turned by pi (pi - 0.02 off +x) and the motion's (pi).
      EXPECT_GE(std::abs(*track.heading_rad), pi - 0.02 - 1e-9);
    } else {
      EXPECT_FALSE(track.heading_rad.has_value());
    }
  }
}

// A car (4.4 x 1.8 m, classed car) driving a circle of radius 20 m at 6 m/s (0.3 rad/s, to the
// left), its whole box seen at 10 Hz with its centre 5 cm and its yaw 2 degrees off at random; then
// unseen for 1.5 s (empty LiDAR frames), then seen again. The oracle is the circle: centre (0, 20),
// the car at angle 0.3 t from (0, 0), heading 0.3 t. The vehicle model predicts the arc through the
// gap, where a constant velocity runs on along the tangent (v w t^2 / 2 = 2 m off after 1.5 s).
TEST(VehicleMotion, ATurningCarsTrackFollowsTheArcThroughAGapAndKeepsItsId) {
  constexpr double kRadius = 20.0, kSpeed = 6.0, kYawRate = kSpeed / kRadius;
  const auto centreAt = [&](double t) {
    return Eigen::Vector2d(kRadius * std::sin(kYawRate * t), kRadius - kRadius * std::cos(kYawRate * t));
  };
  std::mt19937_64 rng(17);
  std::normal_distribution<double> position_noise(0.0, 0.05), yaw_noise(0.0, 2.0 * std::numbers::pi / 180.0);
  auto tracker = makeTracker(TrackerConfig{}, {});
  std::set<std::uint64_t> ids;
  double worst_heading_error = 0.0;
  for (int f = 0; f <= 80; ++f) {
    const double t = 0.1 * f;
    const bool seen = f <= 40 || f > 55;
    std::vector<CloudObservation> observations;
    if (seen) {
      CloudObservation car;
      car.position = {centreAt(t).x() + position_noise(rng), centreAt(t).y() + position_noise(rng), 0.8};
      car.box = OrientedBox{car.position, 4.4, 1.8, 1.5, kYawRate * t + yaw_noise(rng)};
      car.lidar_class = ObjectLabel{ObjectClass::kCar, 0.9};
      car.covariance = Eigen::Vector3d(0.01, 0.01, 0.01).asDiagonal();
      car.point_count = 300;
      observations.push_back(car);
    }
    tracker.addCloud(cloudAt(static_cast<std::int64_t>(f) * 100 * kMs, observations));
    ASSERT_EQ(tracker.tracks().size(), 1U) << "frame " << f;
    const Track& track = tracker.tracks()[0];
    if (track.state != TrackState::kTentative) ids.insert(track.id);
    if (f == 55) {
      EXPECT_LT((track.position - centreAt(t)).norm(), 0.5) << "after 1.5 s unseen: predicted on the arc";
    }
    if (f >= 20 && seen) {
      ASSERT_TRUE(track.heading_rad.has_value()) << "frame " << f;
      worst_heading_error = std::max(worst_heading_error, headingAngleBetween(*track.heading_rad, kYawRate * t));
    }
  }
  EXPECT_EQ(ids.size(), 1U) << "one track all along";
  const Track& car = tracker.tracks()[0];
  EXPECT_LT((car.position - centreAt(8.0)).norm(), 0.15);
  EXPECT_NEAR(car.velocity.norm(), kSpeed, 0.3);
  EXPECT_LT(worst_heading_error, 5.0 * std::numbers::pi / 180.0);
}

}  // namespace
}  // namespace fogmap::tracking
