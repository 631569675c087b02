// Track scoring (harness/track_scoring) against oracles built from the scene's own truth:
// tracks on the true positions score perfectly, offsets show as their size, swapped identities as
// switches, tentative tracks claim nothing, labels split the scores; published track lists are
// placed at their scene instants through the epochs, scored inside one cycle of the scene, their
// latency read from their stamps.
#include "harness/track_scoring.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/sim/generators.hpp"
#include "harness/scene_run.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap::harness {
namespace {

// Two people and a car; no LiDAR or camera is needed to score tracks.
sim::Scene scene() { return sim::movingScene(2, 1, 1, 0, 3); }

// A confirmed track per moving object at its true position at `time_s` moved by `offset`, with id
// 100 + the object's id, labelled as the object.
std::vector<tracking::Track> tracksOnTruth(const sim::Scene& s, double time_s, Eigen::Vector2d offset = Eigen::Vector2d::Zero()) {
  std::vector<tracking::Track> out;
  for (const auto* o : movingObjects(s)) {
    tracking::Track t;
    t.id = 100 + o->id;
    t.label = o->label;
    t.state = tracking::TrackState::kConfirmed;
    t.position = sim::poseAt(*o, time_s).xy + offset;
    out.push_back(t);
  }
  return out;
}

std::vector<TrackingFrame> framesOf(const sim::Scene& s, int count, Eigen::Vector2d offset = Eigen::Vector2d::Zero()) {
  std::vector<TrackingFrame> frames;
  for (int k = 0; k < count; ++k) {
    const double t = 0.1 * k;
    frames.push_back(trackingFrame(s, t, tracksOnTruth(s, t, offset)));
  }
  return frames;
}

TEST(TrackScoring, TheTruthComesFromTheMovingObjectsAtTheInstant) {
  sim::Scene s = scene();
  sim::SceneObject crate;  // standing still: not something to track
  crate.id = 50;
  crate.label = "crate";
  s.objects.push_back(crate);
  ASSERT_EQ(movingObjects(s).size(), 3U);
  const TrackingFrame f = trackingFrame(s, 2.5, {});
  ASSERT_EQ(f.mot.truth.size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(f.mot.truth[i].id, static_cast<std::int64_t>(s.objects[i].id));
    EXPECT_TRUE(f.mot.truth[i].position.isApprox(sim::poseAt(s.objects[i], 2.5).xy));
    EXPECT_EQ(f.truth_labels[i], s.objects[i].label);
  }
}

TEST(TrackScoring, TracksOnTheTruthScorePerfectly) {
  const sim::Scene s = scene();
  const auto scores = scoreTracking(framesOf(s, 40));
  ASSERT_TRUE(scores.ok()) << scores.error().message;
  EXPECT_DOUBLE_EQ(scores->mot.clear.mota, 1.0);
  EXPECT_DOUBLE_EQ(scores->mot.identity.idf1, 1.0);
  EXPECT_EQ(scores->mot.clear.id_switches, 0U);
  EXPECT_EQ(scores->mot.clear.matches, 3U * 40U);
  EXPECT_NEAR(scores->mot.localization.max_m, 0.0, 1e-12);
  EXPECT_EQ(scores->tracks_confirmed, 3U);
  ASSERT_EQ(scores->by_label.size(), 2U);
  EXPECT_EQ(scores->by_label[0].first, "car");  // name order
  EXPECT_EQ(scores->by_label[1].first, "person");
  EXPECT_EQ(scores->by_label[1].second.clear.matches, 2U * 40U);
  EXPECT_DOUBLE_EQ(scores->by_label[0].second.clear.mota, 1.0);
}

TEST(TrackScoring, AnOffsetShowsAsTheLocalizationErrorAndBeyondTheGateAsMissesAndFalsePositives) {
  const sim::Scene s = scene();
  const auto near = scoreTracking(framesOf(s, 20, {0.3, -0.4}));
  ASSERT_TRUE(near.ok());
  EXPECT_NEAR(near->mot.localization.mean_m, 0.5, 1e-9);
  EXPECT_NEAR(near->mot.localization.max_m, 0.5, 1e-9);
  EXPECT_NEAR(near->mot.clear.motp_m, 0.5, 1e-9);
  EXPECT_DOUBLE_EQ(near->mot.clear.mota, 1.0);
  // Far outside the area: near no other object either.
  const auto far = scoreTracking(framesOf(s, 20, {60.0, 0.0}));
  ASSERT_TRUE(far.ok());
  EXPECT_EQ(far->mot.clear.matches, 0U);
  EXPECT_DOUBLE_EQ(far->mot.clear.mota, -1.0) << "every object missed and every track a false positive";
  const auto narrow = scoreTracking(framesOf(s, 20, {0.3, -0.4}), tracking::MotConfig{0.45});
  ASSERT_TRUE(narrow.ok());
  EXPECT_EQ(narrow->mot.clear.matches, 0U) << "the gate is the caller's";
}

// People within kNearRangeM of a LiDAR are scored apart, against the tracks labelled person: a
// scene whose one LiDAR stands at the first person's start, tracks offset 0.3 m.
TEST(TrackScoring, PeopleNearALidarAreScoredApartAgainstThePersonTracks) {
  sim::Scene s = scene();
  ASSERT_FALSE(s.lidars.empty());
  const auto people = movingObjects(s);
  const sim::SceneObject* first = nullptr;
  for (const auto* o : people) {
    if (o->label == "person") {
      first = o;
      break;
    }
  }
  ASSERT_NE(first, nullptr);
  s.lidars.resize(1);
  s.lidars[0].pose.translation().head<2>() = sim::poseAt(*first, 0.0).xy;
  const auto frames = framesOf(s, 20, {0.3, 0.0});
  std::size_t near_people = 0;
  for (const auto& f : frames) {
    ASSERT_EQ(f.truth_near.size(), f.mot.truth.size());
    for (std::size_t j = 0; j < f.truth_near.size(); ++j) {
      const double distance = (s.lidars[0].pose.translation().head<2>() - f.mot.truth[j].position).norm();
      EXPECT_EQ(f.truth_near[j], distance <= kNearRangeM);
      if (f.truth_near[j] && f.truth_labels[j] == "person") ++near_people;
    }
  }
  ASSERT_GT(near_people, 0U);
  const auto scores = scoreTracking(frames);
  ASSERT_TRUE(scores.ok());
  ASSERT_TRUE(scores->people_near.has_value());
  EXPECT_EQ(scores->people_near->clear.matches, near_people);
  EXPECT_NEAR(scores->people_near->localization.mean_m, 0.3, 1e-9);
  // No LiDAR: nobody is near one.
  s.lidars.clear();
  const auto none = scoreTracking(framesOf(s, 20));
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->people_near.has_value());
}

TEST(TrackScoring, SwappedIdentitiesCountAsSwitches) {
  const sim::Scene s = scene();
  std::vector<TrackingFrame> frames;
  for (int k = 0; k < 30; ++k) {
    const double t = 0.1 * k;
    auto tracks = tracksOnTruth(s, t);
    if (k >= 15) std::swap(tracks[0].id, tracks[1].id);  // the two people's tracks trade identities
    frames.push_back(trackingFrame(s, t, tracks));
  }
  const auto scores = scoreTracking(frames);
  ASSERT_TRUE(scores.ok());
  EXPECT_EQ(scores->mot.clear.id_switches, 2U);
  EXPECT_LT(scores->mot.identity.idf1, 1.0);
  EXPECT_EQ(scores->tracks_confirmed, 3U);
}

TEST(TrackScoring, TentativeTracksClaimNothingAndLostOnesStillCount) {
  const sim::Scene s = scene();
  auto tracks = tracksOnTruth(s, 1.0);
  tracks[0].state = tracking::TrackState::kTentative;
  tracks[1].state = tracking::TrackState::kLost;
  EXPECT_FALSE(isHypothesis(tracks[0]));
  EXPECT_TRUE(isHypothesis(tracks[1]));
  const std::vector<TrackingFrame> frames = {trackingFrame(s, 1.0, tracks)};
  ASSERT_EQ(frames[0].mot.hypotheses.size(), 2U);
  EXPECT_EQ(frames[0].confirmed, std::vector<std::uint64_t>{tracks[2].id});
  const auto scores = scoreTracking(frames);
  ASSERT_TRUE(scores.ok());
  EXPECT_EQ(scores->mot.clear.misses, 1U);
  EXPECT_EQ(scores->mot.clear.matches, 2U);
  EXPECT_EQ(scores->tracks_confirmed, 1U);
}

TEST(TrackScoring, ATrackWithTheWrongLabelIsAMissForItsObjectsLabelAndAFalsePositiveForItsOwn) {
  const sim::Scene s = scene();
  auto tracks = tracksOnTruth(s, 1.0);
  ASSERT_EQ(tracks[0].label, "person");
  tracks[0].label = "car";
  const std::vector<TrackingFrame> frames = {trackingFrame(s, 1.0, tracks)};
  const auto scores = scoreTracking(frames);
  ASSERT_TRUE(scores.ok());
  EXPECT_DOUBLE_EQ(scores->mot.clear.mota, 1.0) << "overall, labels do not matter";
  EXPECT_EQ(scores->by_label[0].second.clear.false_positives, 1U);  // car
  EXPECT_EQ(scores->by_label[1].second.clear.misses, 1U);           // person
}

TEST(TrackScoring, HypothesesBeyondTheGateOfEveryTruthAreLeftOut) {
  const std::vector<tracking::MotObject> truth = {{1, {0, 0}}, {2, {10, 0}}};
  const std::vector<tracking::MotObject> hypotheses = {{7, {0.5, 0}}, {8, {5, 0}}, {9, {10, 0.99}}, {10, {11, 0}}};
  const auto kept = withinGateOf(truth, hypotheses, 1.0);
  ASSERT_EQ(kept.size(), 2U);
  EXPECT_EQ(kept[0].id, 7);
  EXPECT_EQ(kept[1].id, 9);
}

TEST(TrackScoring, TheScoringWindowFollowsTheWarmUpAndStaysInsideOneCycleOfTheScene) {
  const std::vector<double> steady = {0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9};
  EXPECT_EQ(scoringWindow(steady, 3, 5), (std::pair<std::size_t, std::size_t>{3, 8}));
  EXPECT_FALSE(scoringWindow(steady, 3, 8)) << "not enough lists yet";
  EXPECT_FALSE(scoringWindow(steady, 0, 0)) << "an empty window is none";
  // The scene's cycle starts again at entry 4: the warm-up starts again there.
  const std::vector<double> wrapped = {59.6, 59.7, 59.8, 59.9, 0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  EXPECT_EQ(scoringWindow(wrapped, 2, 5), (std::pair<std::size_t, std::size_t>{6, 11}));
  EXPECT_EQ(scoringWindow(wrapped, 0, 4), (std::pair<std::size_t, std::size_t>{0, 4})) << "before the wrap";
  EXPECT_FALSE(scoringWindow(wrapped, 2, 6));
  // From a scene time on: where the scene reaches it, after the warm-up, in any cycle.
  const std::vector<double> cycles = {0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  EXPECT_EQ(scoringWindow(cycles, 2, 3, 0.25), (std::pair<std::size_t, std::size_t>{3, 6})) << "0.3 is the first at or after 0.25";
  EXPECT_EQ(scoringWindow(cycles, 2, 4, 0.25), (std::pair<std::size_t, std::size_t>{9, 13})) << "the first cycle wraps too soon";
  EXPECT_EQ(scoringWindow(cycles, 2, 3, 0.2), (std::pair<std::size_t, std::size_t>{2, 5}));
  EXPECT_FALSE(scoringWindow(cycles, 3, 3, 0.2)) << "two lists of warm-up before it in each cycle, not three";
  EXPECT_FALSE(scoringWindow(cycles, 0, 2, 0.7)) << "the scene never reaches it";
  // A run that starts past the time waits for the next cycle: its first stretch opens after it.
  const std::vector<double> late = {0.3, 0.4, 0.5, 0.0, 0.1, 0.2, 0.3, 0.4};
  EXPECT_EQ(scoringWindow(late, 1, 2, 0.3), (std::pair<std::size_t, std::size_t>{6, 8}));
  EXPECT_EQ(scoringWindow(late, 0, 2, 0.3), (std::pair<std::size_t, std::size_t>{0, 2})) << "no warm-up: the opening entry counts";
}

TEST(TrackScoring, ALidarFramesSceneInstantIsItsEpochsScan) {
  const sim::Scene s = scene();  // 60 s at 10 Hz: 600 frames a cycle
  const auto schedule = EpochSchedule::create(100.0, 80.0);
  ASSERT_TRUE(schedule.ok());
  const std::uint64_t epoch = 17'000'000'123ULL;  // a unix time in 2023, in 100 ms epochs
  // The earliest edge's sensor time lies anywhere in the epoch's window.
  for (const std::int64_t late_ns : {0LL, 5'000'000LL, 99'000'000LL}) {
    EXPECT_NEAR(sceneTimeOf(s, *schedule, 10.0, schedule->startNs(epoch) + late_ns), static_cast<double>(epoch % 600) * 0.1, 1e-9);
  }
}

// Track lists as a tracker would publish them from `first_epoch` on: tracks on the truth of each
// list's instant, published `latency_ms(k)` after the LiDAR frame.
std::vector<PublishedTracks> published(const sim::Scene& s, const EpochSchedule& schedule, std::uint64_t first_epoch, int count,
                                       const std::function<double(int)>& latency_ms) {
  std::vector<PublishedTracks> lists;
  for (int k = 0; k < count; ++k) {
    PublishedTracks list;
    list.lidar_time_ns = schedule.startNs(first_epoch + static_cast<std::uint64_t>(k)) + 2'000'000;
    list.published_time_ns = list.lidar_time_ns + static_cast<std::int64_t>(std::llround(latency_ms(k) * 1e6));
    list.tracks = tracksOnTruth(s, sceneTimeOf(s, schedule, 10.0, list.lidar_time_ns));
    lists.push_back(std::move(list));
  }
  return lists;
}

TEST(TrackScoring, PublishedTracksAreScoredInsideOneCycleWithTheirLatency) {
  const sim::Scene s = scene();
  const auto schedule = EpochSchedule::create(100.0, 80.0);
  ASSERT_TRUE(schedule.ok());
  // 20 lists before the scene's cycle wraps (epoch 600 k), then 40 after it; one slow list.
  const std::uint64_t first = 600ULL * 28'000'000ULL - 20;
  const auto lists = published(s, *schedule, first, 60, [](int k) { return k == 40 ? 90.0 : 40.0 + 0.01 * k; });
  const auto scored = scorePublishedTracks(s, *schedule, 10.0, lists, 5, 30);
  ASSERT_TRUE(scored.ok()) << scored.error().message;
  EXPECT_EQ(scored->first_list, 25U) << "five lists after the wrap";
  EXPECT_EQ(scored->frames, 30U);
  EXPECT_NEAR(scored->first_time_s, 0.5, 1e-9);
  EXPECT_NEAR(scored->last_time_s, 3.4, 1e-9);
  EXPECT_DOUBLE_EQ(scored->scores.mot.clear.mota, 1.0);
  EXPECT_EQ(scored->scores.mot.clear.matches, 90U);
  // Latencies 40.25 .. 40.54 ms but 40.40, and one of 90 ms: the 15th and 29th of 30, and the max.
  EXPECT_NEAR(scored->latency_p50_ms, 40.39, 1e-6);
  EXPECT_NEAR(scored->latency_p95_ms, 40.54, 1e-6);
  EXPECT_NEAR(scored->latency_max_ms, 90.0, 1e-6);
  const auto too_short = scorePublishedTracks(s, *schedule, 10.0, std::span(lists).first(50), 5, 30);
  ASSERT_FALSE(too_short.ok());
  EXPECT_NE(too_short.error().message.find("50 track lists"), std::string::npos) << too_short.error().message;
}

// The demo's track_lists.jsonl: one JSON line per scored list, in order, with the list's scene
// instant, the truth there and the tracks as scored; a run whose topology has no valid epoch
// schedule is refused with the reason, not written as an empty file.
TEST(TrackScoring, TheScoredListsAreOneJsonLineEachAndARunWithoutAScheduleIsRefused) {
  const sim::Scene s = scene();
  const auto schedule = EpochSchedule::create(100.0, 80.0);
  ASSERT_TRUE(schedule.ok());
  SceneTrackingRun run;
  run.topology.period_ms = 100.0;
  run.topology.deadline_ms = 80.0;
  run.lists = published(s, *schedule, 600ULL * 28'000'000ULL + 10, 12, [](int) { return 40.0; });
  run.lists[5].tracks[0].state = tracking::TrackState::kLost;
  SceneTrackingOptions options;
  const auto scored = scorePublishedTracks(s, *schedule, options.rate_hz, run.lists, 2, 8);
  ASSERT_TRUE(scored.ok()) << scored.error().message;
  ASSERT_EQ(scored->first_list, 2U) << "list 5, with its lost track, among the scored ones";
  const auto text = sceneTrackListsJsonLines(s, run, *scored, options);
  ASSERT_TRUE(text.ok()) << text.error().message;
  std::vector<nlohmann::json> lines;
  for (std::size_t at = 0, end = 0; (end = text->find('\n', at)) != std::string::npos; at = end + 1) {
    lines.push_back(nlohmann::json::parse(text->substr(at, end - at)));
  }
  ASSERT_EQ(lines.size(), 8U);
  for (std::size_t k = 0; k < lines.size(); ++k) {
    const auto& line = lines[k];
    const std::size_t list = scored->first_list + k;
    EXPECT_EQ(line["list"].get<std::size_t>(), list);
    const double time_s = sceneTimeOf(s, *schedule, options.rate_hz, run.lists[list].lidar_time_ns);
    EXPECT_NEAR(line["scene_time_s"].get<double>(), time_s, 1e-9);
    ASSERT_EQ(line["truth"].size(), 3U);
    ASSERT_EQ(line["tracks"].size(), 3U);
    for (std::size_t i = 0; i < 3; ++i) {
      const auto& truth = line["truth"][i];
      const auto& track = line["tracks"][i];
      EXPECT_EQ(truth["label"], track["label"]);
      EXPECT_EQ(track["id"].get<std::int64_t>(), 100 + truth["id"].get<std::int64_t>());
      EXPECT_NEAR(track["x"].get<double>(), truth["x"].get<double>(), 1e-9);
      EXPECT_NEAR(track["y"].get<double>(), truth["y"].get<double>(), 1e-9);
      EXPECT_EQ(track["confirmed"].get<bool>(), !(list == 5 && i == 0)) << "a lost track is scored, not confirmed";
    }
  }
  run.topology.period_ms = 0.0;
  const auto refused = sceneTrackListsJsonLines(s, run, *scored, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("period_ms"), std::string::npos) << refused.error().message;
}

}  // namespace
}  // namespace fogmap::harness
