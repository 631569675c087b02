// Object-level accuracy by range band and kind (harness/object_breakdown.*) against hand-placed
// scenes whose bands are known, and against the totals on random outcomes: every band edge, the
// nearest of several LiDARs on the ground plane, moving objects where they are at the frame, the
// scene's own labels as kinds, and the reports' keys and rows.
#include "harness/object_breakdown.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "harness/evaluation.hpp"

namespace fogmap::harness {
namespace {

sim::LidarConfig lidarAt(const std::string& name, double x, double y, double z) {
  sim::LidarConfig l;
  l.name = name;
  l.pose.translation() = Eigen::Vector3d(x, y, z);
  return l;
}

sim::SceneObject objectAt(std::uint32_t id, const std::string& label, double x, double y) {
  sim::SceneObject o;
  o.id = id;
  o.label = label;
  o.name = label + "-" + std::to_string(id);
  o.xy = Eigen::Vector2d(x, y);
  return o;
}

ObjectOutcome outcome(std::int64_t object, bool whole, bool split, bool merged, bool missed) {
  return {object, 20, whole, split, merged, missed};
}

bool sameCounts(const ObjectMatch& a, const ObjectMatch& b) {
  return a.objects_true == b.objects_true && a.found_whole == b.found_whole && a.split == b.split && a.merged == b.merged &&
         a.missed == b.missed;
}

// Two LiDARs 60 m apart, one high up: objects at known horizontal distances from the nearer.
sim::Scene twoLidarScene() {
  sim::Scene scene;
  scene.name = "two-lidars";
  scene.lidars = {lidarAt("west", 0, 0, 1.8), lidarAt("east", 60, 0, 30.0)};
  scene.objects = {objectAt(1, "person", 5, 0),     // 5 m from west: 0-10
                   objectAt(2, "person", 0, 15),    // 15 m from west: 10-20
                   objectAt(3, "car", 30, 25),      // sqrt(30^2 + 25^2) = 39.05 m from either: 20-40
                   objectAt(4, "car", 30, -45),     // 54.08 m from either: 40+
                   objectAt(5, "crate", 52, 0),     // 8 m from east on the ground (30 m up does not count): 0-10
                   objectAt(6, "", -20, 0)};        // no label: "other"; 20 m: 20-40
  return scene;
}

TEST(ObjectBreakdown, RangeBandsSplitAtTenTwentyAndFortyMetres) {
  EXPECT_EQ(rangeBand(0.0), "0-10");
  EXPECT_EQ(rangeBand(9.999), "0-10");
  EXPECT_EQ(rangeBand(10.0), "10-20");
  EXPECT_EQ(rangeBand(19.999), "10-20");
  EXPECT_EQ(rangeBand(20.0), "20-40");
  EXPECT_EQ(rangeBand(39.999), "20-40");
  EXPECT_EQ(rangeBand(40.0), "40+");
  EXPECT_EQ(rangeBand(1e6), "40+");
  EXPECT_EQ(rangeBand(std::numeric_limits<double>::infinity()), "40+");
  EXPECT_EQ(rangeBand(std::nan("")), "40+");
}

TEST(ObjectBreakdown, TheNearestLidarOnTheGroundPlaneDecidesTheBand) {
  const sim::Scene scene = twoLidarScene();
  EXPECT_DOUBLE_EQ(nearestLidarDistance(scene, {52, 0}), 8.0) << "the east LiDAR's height is no distance";
  EXPECT_DOUBLE_EQ(nearestLidarDistance(scene, {0, 15}), 15.0);
  EXPECT_NEAR(nearestLidarDistance(scene, {30, 25}), std::hypot(30.0, 25.0), 1e-12);
  EXPECT_TRUE(std::isinf(nearestLidarDistance(sim::Scene{}, {0, 0}))) << "no LiDAR";

  std::vector<ObjectOutcome> outcomes;
  for (std::int64_t id = 1; id <= 6; ++id) outcomes.push_back(outcome(id, true, false, false, false));
  const auto b = breakDownObjects(scene, 0.0, outcomes);
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_EQ(b->by_range_band.at("0-10").objects_true, 2U);   // objects 1 and 5
  EXPECT_EQ(b->by_range_band.at("10-20").objects_true, 1U);  // 2
  EXPECT_EQ(b->by_range_band.at("20-40").objects_true, 2U);  // 3 and 6
  EXPECT_EQ(b->by_range_band.at("40+").objects_true, 1U);    // 4
}

TEST(ObjectBreakdown, KindsAreTheScenesLabelsAndEveryBandAndKindIsListed) {
  const sim::Scene scene = twoLidarScene();
  // Only objects 1 (person, missed) and 3 (car, split and merged) counted in this frame.
  const std::vector<ObjectOutcome> outcomes = {outcome(1, false, false, false, true), outcome(3, false, true, true, false)};
  const auto b = breakDownObjects(scene, 0.0, outcomes);
  ASSERT_TRUE(b.ok()) << b.error().message;
  ASSERT_EQ(b->by_kind.size(), 4U);
  EXPECT_TRUE(sameCounts(b->by_kind.at("person"), {1, 0, 0, 0, 1}));
  EXPECT_TRUE(sameCounts(b->by_kind.at("car"), {1, 0, 1, 1, 0}));
  EXPECT_TRUE(sameCounts(b->by_kind.at("crate"), {}));
  EXPECT_TRUE(sameCounts(b->by_kind.at(kOtherKind), {})) << "the unlabelled object's kind";
  ASSERT_EQ(b->by_range_band.size(), 4U);
  EXPECT_TRUE(sameCounts(b->by_range_band.at("0-10"), {1, 0, 0, 0, 1}));
  EXPECT_TRUE(sameCounts(b->by_range_band.at("20-40"), {1, 0, 1, 1, 0}));
  EXPECT_TRUE(sameCounts(b->by_range_band.at("10-20"), {}));
  EXPECT_TRUE(sameCounts(b->by_range_band.at("40+"), {}));
}

TEST(ObjectBreakdown, AMovingObjectIsBandedWhereItIsAtTheFrame) {
  sim::Scene scene;
  scene.lidars = {lidarAt("l", 0, 0, 1.8)};
  sim::SceneObject walker = objectAt(1, "person", 5, 0);
  walker.motion.velocity_mps = Eigen::Vector2d(1.0, 0.0);
  scene.objects = {walker};
  const std::vector<ObjectOutcome> missed = {outcome(1, false, false, false, true)};
  const auto at_start = breakDownObjects(scene, 0.0, missed);
  const auto later = breakDownObjects(scene, 10.0, missed);  // 15 m out
  const auto much_later = breakDownObjects(scene, 40.0, missed);  // 45 m out
  ASSERT_TRUE(at_start.ok() && later.ok() && much_later.ok());
  EXPECT_EQ(at_start->by_range_band.at("0-10").missed, 1U);
  EXPECT_EQ(later->by_range_band.at("10-20").missed, 1U);
  EXPECT_EQ(later->by_range_band.at("0-10").missed, 0U);
  EXPECT_EQ(much_later->by_range_band.at("40+").missed, 1U);
  const auto centres = missedCentres(scene, 10.0, missed);
  ASSERT_TRUE(centres.ok());
  ASSERT_EQ(centres->size(), 1U);
  EXPECT_TRUE(centres->front().isApprox(Eigen::Vector2d(15, 0)));
}

TEST(ObjectBreakdown, MissedCentresAreTheMissedObjectsOnly) {
  const sim::Scene scene = twoLidarScene();
  const std::vector<ObjectOutcome> outcomes = {outcome(1, true, false, false, false), outcome(4, false, false, false, true),
                                               outcome(5, false, true, false, true), outcome(6, false, false, true, false)};
  const auto centres = missedCentres(scene, 0.0, outcomes);
  ASSERT_TRUE(centres.ok());
  ASSERT_EQ(centres->size(), 2U);
  EXPECT_TRUE((*centres)[0].isApprox(Eigen::Vector2d(30, -45)));
  EXPECT_TRUE((*centres)[1].isApprox(Eigen::Vector2d(52, 0)));
  EXPECT_TRUE(missedCentres(scene, 0.0, std::vector<ObjectOutcome>{})->empty());
}

TEST(ObjectBreakdown, AnObjectTheSceneDoesNotHaveIsAnError) {
  const sim::Scene scene = twoLidarScene();
  const std::vector<ObjectOutcome> stranger = {outcome(99, false, false, false, true)};
  const auto b = breakDownObjects(scene, 0.0, stranger);
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(b.error().message.find("99"), std::string::npos) << b.error().message;
  EXPECT_FALSE(missedCentres(scene, 0.0, stranger).ok());
}

TEST(ObjectBreakdown, BandsAndKindsEachSumToTheFrameTotalsOnRandomOutcomes) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> coord(-60.0, 60.0);
    std::uniform_int_distribution<int> label(0, 3);
    std::bernoulli_distribution coin(0.4);
    sim::Scene scene;
    scene.lidars = {lidarAt("a", coord(rng), coord(rng), 2.0), lidarAt("b", coord(rng), coord(rng), 2.0)};
    const std::vector<std::string> labels = {"person", "car", "pole", ""};
    for (std::uint32_t id = 1; id <= 30; ++id) scene.objects.push_back(objectAt(id, labels[label(rng)], coord(rng), coord(rng)));
    ObjectBreakdown sum = emptyBreakdown(scene);
    std::vector<ObjectOutcome> all;
    for (int frame = 0; frame < 3; ++frame) {
      std::vector<ObjectOutcome> outcomes;
      for (std::uint32_t id = 1; id <= 30; ++id) {
        if (!coin(rng)) continue;
        const bool missed = coin(rng);
        const bool split = coin(rng);
        const bool merged = !missed && coin(rng);
        outcomes.push_back(outcome(id, !missed && !split && !merged, split, merged, missed));
      }
      const auto b = breakDownObjects(scene, 0.0, outcomes);
      ASSERT_TRUE(b.ok());
      addBreakdown(sum, *b);
      all.insert(all.end(), outcomes.begin(), outcomes.end());
    }
    const ObjectMatch total = countOutcomes(all);
    ObjectMatch over_bands, over_kinds;
    for (const auto& [band, m] : sum.by_range_band) addObjectMatch(over_bands, m);
    for (const auto& [kind, m] : sum.by_kind) addObjectMatch(over_kinds, m);
    EXPECT_TRUE(sameCounts(over_bands, total)) << "seed " << seed;
    EXPECT_TRUE(sameCounts(over_kinds, total)) << "seed " << seed;
    // Each object in the band of its distance, counted by hand.
    std::size_t near = 0;
    for (const auto& o : all) {
      const auto& object = scene.objects[static_cast<std::size_t>(o.true_object - 1)];
      near += nearestLidarDistance(scene, object.xy) < 10.0 ? 1 : 0;
    }
    EXPECT_EQ(sum.by_range_band.at("0-10").objects_true, near) << "seed " << seed;
  }
}

TEST(ObjectBreakdown, ScoringAgainstTheTruthKeepsTheOutcomesItCounted) {
  EdgeView view;
  view.truth[1] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, -1, -1};
  view.truth[2] = {2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3};
  PointObjects found;
  found[1] = {7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 8, 8, 8, 8, 8, 8, 8, 8, 8, 8, -1, -2};
  found[2] = {9, 9, 9, 9, 9, -3, -4, -5, -6, -7, -8, -9, -10, -11, -12, -13};  // object 3 missed
  const auto scores = scoreAgainstTruth(found, view);
  ASSERT_TRUE(scores.ok()) << scores.error().message;
  ASSERT_EQ(scores->outcomes.size(), 3U);
  EXPECT_TRUE(sameCounts(scores->objects, countOutcomes(scores->outcomes)));
  EXPECT_TRUE(scores->outcomes[0].found_whole);
  EXPECT_TRUE(scores->outcomes[1].split && !scores->outcomes[1].missed) << "object 2: 10 points in 8, 5 in 9";
  EXPECT_TRUE(scores->outcomes[2].missed);
  EXPECT_EQ(scores->outcomes[2].true_object, 3);
  EXPECT_EQ(scores->outcomes[2].points, 11U);
}

TEST(ObjectBreakdown, TheReportsListEveryBandInOrderAndEveryKindWithTheFiveCounts) {
  const sim::Scene scene = twoLidarScene();
  const std::vector<ObjectOutcome> madc_outcomes = {outcome(1, false, false, false, true), outcome(2, true, false, false, false),
                                                    outcome(3, false, true, true, false)};
  const std::vector<ObjectOutcome> base_outcomes = {outcome(1, true, false, false, false), outcome(2, true, false, false, false)};
  const auto madc = breakDownObjects(scene, 0.0, madc_outcomes);
  const auto baseline = breakDownObjects(scene, 0.0, base_outcomes);
  ASSERT_TRUE(madc.ok() && baseline.ok());
  const Json bands = rangeBandReport(*madc, *baseline);
  ASSERT_TRUE(bands.contains("madc") && bands.contains("baseline"));
  std::vector<std::string> keys;
  for (const auto& [key, value] : bands["madc"].items()) keys.push_back(key);
  EXPECT_EQ(keys, (std::vector<std::string>{"0-10", "10-20", "20-40", "40+"}));
  EXPECT_EQ(bands["madc"]["0-10"], Json::parse(R"({"true": 1, "found_whole": 0, "split": 0, "merged": 0, "missed": 1})"));
  EXPECT_EQ(bands["madc"]["20-40"]["split"], 1);
  EXPECT_EQ(bands["baseline"]["0-10"]["found_whole"], 1);
  EXPECT_EQ(bands["baseline"]["40+"]["true"], 0);
  const Json kinds = kindReport(*madc, *baseline);
  EXPECT_EQ(kinds["madc"]["person"]["true"], 2);
  EXPECT_EQ(kinds["madc"]["person"]["missed"], 1);
  EXPECT_EQ(kinds["madc"]["car"]["merged"], 1);
  EXPECT_EQ(kinds["baseline"]["car"]["true"], 0);
  EXPECT_TRUE(kinds["baseline"].contains(kOtherKind));

  const std::string text = objectBreakdownText(*madc, *baseline);
  EXPECT_NE(text.find("MAD-C"), std::string::npos) << text;
  EXPECT_NE(text.find("baseline"), std::string::npos) << text;
  EXPECT_LT(text.find("MAD-C"), text.find("baseline")) << text;
  EXPECT_NE(text.find("0-10 m"), std::string::npos) << text;
  EXPECT_NE(text.find("40+ m"), std::string::npos) << text;
  EXPECT_NE(text.find("person"), std::string::npos) << text;
  // MAD-C's person row: 2 true, 1 whole, 0 split, 0 merged, 1 missed.
  EXPECT_NE(text.find("person                 2       1       0       0       1"), std::string::npos) << text;

  const std::vector<BreakdownRow> rows = {{"2 LiDARs", &*madc, &*baseline}};
  const std::string md = objectBreakdownMarkdown("configuration", rows);
  EXPECT_NE(md.find("| configuration | system | 0-10 m | 10-20 m | 20-40 m | 40+ m |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 2 LiDARs | MAD-C | 0 / 0 / 0 / 1 of 1 | 1 / 0 / 0 / 0 of 1 | 0 / 1 / 1 / 0 of 1 | 0 / 0 / 0 / 0 of 0 |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| configuration | system | car | crate | other | person |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 2 LiDARs | baseline | 0 / 0 / 0 / 0 of 0 | 0 / 0 / 0 / 0 of 0 | 0 / 0 / 0 / 0 of 0 | 2 / 0 / 0 / 0 of 2 |"),
            std::string::npos)
      << md;
}

}  // namespace
}  // namespace fogmap::harness
