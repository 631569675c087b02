// Scoring against the truth of a simulated scene (harness/evaluation.*), checked against
// hand-computed answers and brute-force oracles: per-point global objects, all-pairs Rand index,
// matchObjects' documented rules, and ellipsoids built from first principles.
#include "harness/evaluation.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "common/perception/madc.hpp"

namespace fogmap::harness {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers.

Ellipsoid ellipsoidWithId(std::uint32_t node, std::uint64_t frame, std::uint32_t index) {
  Ellipsoid e;
  e.id = {node, frame, index};
  return e;
}

MapObject objectOf(std::vector<Ellipsoid> ellipsoids) {
  MapObject o;
  o.ellipsoids = std::move(ellipsoids);
  return o;
}

bool mentions(const Error& error, const std::string& text) { return error.message.find(text) != std::string::npos; }

// Every negative label of `objects` (over all nodes); fails the test if one repeats.
std::size_t expectNegativesUnique(const PointObjects& objects) {
  std::set<std::int64_t> seen;
  std::size_t count = 0;
  for (const auto& [node, labels] : objects) {
    for (const auto l : labels) {
      if (l >= 0) continue;
      ++count;
      EXPECT_TRUE(seen.insert(l).second) << "negative label " << l << " used twice (node " << node << ")";
    }
  }
  return count;
}

// The Rand and adjusted Rand index by counting every pair: two points are together in a partition
// when they share a non-negative label (negative: a singleton).
RandScores bruteForceRand(const std::vector<std::int64_t>& found, const std::vector<std::int64_t>& truth) {
  const std::size_t n = found.size();
  double total = 0, agree = 0, together_found = 0, together_truth = 0, together_both = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      const bool f = found[i] >= 0 && found[i] == found[j];
      const bool t = truth[i] >= 0 && truth[i] == truth[j];
      total += 1;
      agree += f == t ? 1 : 0;
      together_found += f ? 1 : 0;
      together_truth += t ? 1 : 0;
      together_both += f && t ? 1 : 0;
    }
  }
  const double expected = together_found * together_truth / total;
  return {agree / total, (together_both - expected) / (0.5 * (together_found + together_truth) - expected)};
}

// n points of object `object` found in `found` (found < 0: each point its own fresh negative).
void addPoints(std::vector<std::int64_t>& truth, std::vector<std::int64_t>& found, std::int64_t object,
               std::int64_t cluster, int n, std::int64_t& next_noise) {
  for (int i = 0; i < n; ++i) {
    truth.push_back(object);
    found.push_back(cluster >= 0 ? cluster : next_noise--);
  }
}

// A 5 x 5 x 5 grid with spacing 0.25 m filling the unit cube at `corner` (every coordinate exact
// in float). Per axis the variance is 0.125 m^2, so the corners lie at Mahalanobis distance
// sqrt(6) ~ 2.45 from the centre, which is itself a grid point.
Cloud gridBox(const Eigen::Vector3d& corner) {
  Cloud out;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      for (int k = 0; k < 5; ++k) {
        out.push_back({static_cast<float>(corner.x() + 0.25 * i), static_cast<float>(corner.y() + 0.25 * j),
                       static_cast<float>(corner.z() + 0.25 * k), 0.0F});
      }
    }
  }
  return out;
}
constexpr double kGridPoints = 125.0;

// One node's share of a view: points, local labels, truth.
struct NodeScene {
  Cloud points;
  std::vector<std::int32_t> labels;
  std::vector<std::int64_t> truth;
  void add(const Cloud& cloud, std::int32_t label, std::int64_t object) {
    points.insert(points.end(), cloud.begin(), cloud.end());
    labels.insert(labels.end(), cloud.size(), label);
    truth.insert(truth.end(), cloud.size(), object);
  }
};

void putNode(EdgeView& view, std::uint32_t node, const NodeScene& scene) {
  view.points[node] = scene.points;
  view.local_labels[node] = scene.labels;
  view.truth[node] = scene.truth;
}

// The specification, from first principles and without an aura: for every local cluster whose
// points are mostly (a strict plurality, "none" included) of one true object, its ellipsoid is
// {x : (x - mean)^T (alpha^2 Sigma)^-1 (x - mean) <= 1} with the two-pass maximum-likelihood
// covariance; precision and recall counted over every point of the node, averaged over clusters.
PrecisionRecall bruteForcePrecisionRecall(const EdgeView& view, double alpha) {
  PrecisionRecall out;
  for (const auto& [node, truth] : view.truth) {
    const Cloud& points = view.points.at(node);
    const auto& labels = view.local_labels.at(node);
    const std::set<std::int32_t> clusters(labels.begin(), labels.end());
    for (const auto c : clusters) {
      if (c < 0) continue;
      std::vector<Eigen::Vector3d> members;
      std::map<std::int64_t, std::size_t> votes;  // -1: no true object
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (labels[i] != c) continue;
        members.emplace_back(points[i].x, points[i].y, points[i].z);
        ++votes[truth[i] >= 0 ? truth[i] : -1];
      }
      std::int64_t object = -1;
      std::size_t most = 0;
      for (const auto& [o, n] : votes) {
        if (n > most) {
          most = n;
          object = o;
        }
      }
      if (object < 0) continue;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const auto& p : members) mean += p;
      mean /= static_cast<double>(members.size());
      Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
      for (const auto& p : members) sigma += (p - mean) * (p - mean).transpose();
      sigma /= static_cast<double>(members.size());
      const Eigen::Matrix3d inverse = (alpha * alpha * sigma).inverse();
      double covered = 0, correct = 0, of_object = 0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (truth[i] == object) ++of_object;
        const Eigen::Vector3d d = Eigen::Vector3d(points[i].x, points[i].y, points[i].z) - mean;
        if (d.dot(inverse * d) > 1.0) continue;
        ++covered;
        if (truth[i] == object) ++correct;
      }
      out.precision += covered > 0 ? correct / covered : 0.0;
      out.recall += correct / of_object;
      ++out.clusters;
    }
  }
  if (out.clusters > 0) {
    out.precision /= static_cast<double>(out.clusters);
    out.recall /= static_cast<double>(out.clusters);
  }
  return out;
}

// Two boxes 10 m apart on node 1, clustered by the edges' own code (genLocalMap: each box is one
// cluster at eps 0.35 m), each box its own true object (7 and 9).
EdgeView twoBoxes() {
  NodeScene scene;
  scene.add(gridBox({0, 0, 0}), 0, 7);
  scene.add(gridBox({10, 0, 0}), 0, 9);
  const auto local = genLocalMap(scene.points, 1, 0, MadcParams{}).value();
  EXPECT_EQ(local.clustering.cluster_count, 2);
  scene.labels = local.clustering.labels;
  EdgeView view;
  putNode(view, 1, scene);
  return view;
}

constexpr EllipsoidParams kCoveringNoAura{3.0, 0.0};  // alpha^2 = 9 > 6: the whole box is inside

// ---------------------------------------------------------------------------------------------
// madcPointObjects

TEST(EvaluationMadcPointObjects, EveryPointGetsTheObjectHoldingItsClustersEllipsoid) {
  EdgeView view;
  view.local_labels[1] = {0, 0, 1, -1, 1, 2};
  view.local_labels[2] = {0, -1, 1, 1, 0};
  GlobalMapMessage madc;
  madc.header.epoch = 7;
  madc.map.objects.push_back(objectOf({ellipsoidWithId(1, 7, 0), ellipsoidWithId(2, 7, 1)}));  // object 0
  madc.map.objects.push_back(objectOf({ellipsoidWithId(1, 7, 1), ellipsoidWithId(2, 7, 0)}));  // object 1
  // Node 1's cluster 2 of this epoch is missing; an ellipsoid with its index but of another epoch,
  // and one of a node outside the view, must not stand in for it.
  madc.map.objects.push_back(objectOf({ellipsoidWithId(1, 6, 2), ellipsoidWithId(3, 7, 2)}));  // object 2

  const PointObjects objects = madcPointObjects(madc, view);
  ASSERT_EQ(objects.size(), 2U);
  const auto& n1 = objects.at(1);
  const auto& n2 = objects.at(2);
  ASSERT_EQ(n1.size(), 6U);
  ASSERT_EQ(n2.size(), 5U);
  EXPECT_EQ(n1[0], 0);
  EXPECT_EQ(n1[1], 0);
  EXPECT_EQ(n1[2], 1);
  EXPECT_LT(n1[3], 0);  // noise
  EXPECT_EQ(n1[4], 1);
  EXPECT_LT(n1[5], 0);  // cluster missing from the map
  EXPECT_EQ(n2[0], 1);
  EXPECT_LT(n2[1], 0);  // noise
  EXPECT_EQ(n2[2], 0);
  EXPECT_EQ(n2[3], 0);
  EXPECT_EQ(n2[4], 1);
  EXPECT_EQ(expectNegativesUnique(objects), 3U);
}

TEST(EvaluationMadcPointObjects, PointsOfAClusterMissingFromTheMapAreSingletons) {
  EdgeView view;
  view.local_labels[4] = {0, 0, 0, -1, -1};
  view.local_labels[5] = {-1, 0, 0};
  GlobalMapMessage madc;  // empty map: nothing is an object
  madc.header.epoch = 3;
  const PointObjects objects = madcPointObjects(madc, view);
  ASSERT_EQ(objects.at(4).size(), 5U);
  ASSERT_EQ(objects.at(5).size(), 3U);
  EXPECT_EQ(expectNegativesUnique(objects), 8U);
}

// ---------------------------------------------------------------------------------------------
// baselinePointObjects

TEST(EvaluationBaselinePointObjects, TakesTheCentralLabelsAndMakesEveryNegativeUnique) {
  EdgeView view;
  view.local_labels[4] = std::vector<std::int32_t>(6, 0);  // the edges' own labels do not matter
  view.local_labels[9] = std::vector<std::int32_t>(5, -1);
  GlobalMapMessage baseline;
  baseline.mode = Mode::kBaseline;
  baseline.point_labels.push_back({9, {5, -1, -2, 3, 3}});
  baseline.point_labels.push_back({4, {3, 3, -1, 5, -1, 4}});
  baseline.point_labels.push_back({12, {0, 0}});  // a node outside the view is not looked at

  const auto objects = baselinePointObjects(baseline, view);
  ASSERT_TRUE(objects.ok()) << objects.error().message;
  ASSERT_EQ(objects->size(), 2U);
  const std::vector<std::int64_t> want4{3, 3, -1, 5, -1, 4};
  const std::vector<std::int64_t> want9{5, -1, -2, 3, 3};
  const auto& got4 = objects->at(4);
  const auto& got9 = objects->at(9);
  ASSERT_EQ(got4.size(), want4.size());
  ASSERT_EQ(got9.size(), want9.size());
  for (std::size_t i = 0; i < want4.size(); ++i) {
    if (want4[i] >= 0) EXPECT_EQ(got4[i], want4[i]) << "node 4 point " << i;
    else EXPECT_LT(got4[i], 0) << "node 4 point " << i;
  }
  for (std::size_t i = 0; i < want9.size(); ++i) {
    if (want9[i] >= 0) EXPECT_EQ(got9[i], want9[i]) << "node 9 point " << i;
    else EXPECT_LT(got9[i], 0) << "node 9 point " << i;
  }
  EXPECT_EQ(expectNegativesUnique(*objects), 4U);
}

TEST(EvaluationBaselinePointObjects, AMissingNodeIsAnErrorNamingIt) {
  EdgeView view;
  view.local_labels[4] = {0, 0};
  view.local_labels[9] = {0, 0, 0};
  GlobalMapMessage baseline;
  baseline.point_labels.push_back({4, {1, 1}});
  const auto objects = baselinePointObjects(baseline, view);
  ASSERT_FALSE(objects.ok());
  EXPECT_EQ(objects.error().code, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(mentions(objects.error(), "node 9")) << objects.error().message;
}

TEST(EvaluationBaselinePointObjects, ALengthMismatchIsAnErrorNamingTheNode) {
  EdgeView view;
  view.local_labels[4] = {0, 0};
  view.local_labels[9] = {0, 0, 0};
  GlobalMapMessage baseline;
  baseline.point_labels.push_back({4, {1, 1}});
  baseline.point_labels.push_back({9, {1, 1, 1, 1}});
  const auto objects = baselinePointObjects(baseline, view);
  ASSERT_FALSE(objects.ok());
  EXPECT_EQ(objects.error().code, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(mentions(objects.error(), "node 9")) << objects.error().message;
  EXPECT_FALSE(mentions(objects.error(), "node 4")) << objects.error().message;
}

// ---------------------------------------------------------------------------------------------
// scoreAgainstTruth

TEST(EvaluationScoreAgainstTruth, IdenticalPartitionsScoreOneAndFindEveryObjectWhole) {
  EdgeView view;
  PointObjects objects;
  std::int64_t noise = -1;
  for (std::uint32_t node : {1U, 2U}) {
    std::vector<std::int64_t> truth, found;
    addPoints(truth, found, 0, 0, 12, noise);    // object 0 seen by both nodes
    addPoints(truth, found, 1 + node, 1 + node, 15, noise);  // one object per node
    for (int i = 0; i < 4; ++i) {  // ground: no object, noise in the output
      truth.push_back(-1);
      found.push_back(noise--);
    }
    view.truth[node] = truth;
    objects[node] = found;
  }
  const auto scores = scoreAgainstTruth(objects, view);
  ASSERT_TRUE(scores.ok()) << scores.error().message;
  EXPECT_EQ(scores->point_count, 2U * (12 + 15 + 4));
  EXPECT_DOUBLE_EQ(scores->points.rand_index, 1.0);
  EXPECT_DOUBLE_EQ(scores->points.adjusted_rand_index, 1.0);
  EXPECT_EQ(scores->objects.objects_true, 3U);
  EXPECT_EQ(scores->objects.found_whole, 3U);
  EXPECT_EQ(scores->objects.split + scores->objects.merged + scores->objects.missed, 0U);
}

TEST(EvaluationScoreAgainstTruth, MergedObjectsAreCountedAndTheRandIndexCountsEveryPair) {
  // Per matchObjects' rules (min_points 10, found 0.5, share 0.1):
  std::vector<std::int64_t> t1, f1, t2, f2;
  std::int64_t noise = -1;
  addPoints(t1, f1, 0, 7, 12, noise);   // objects 0 and 1 both in found 7: merged, merged
  addPoints(t1, f1, 1, 7, 15, noise);
  addPoints(t1, f1, -1, -1, 3, noise);  // ground as noise ...
  addPoints(t1, f1, -1, 3, 2, noise);   // ... and in found 3, which does not make object 2 merged
  addPoints(t2, f2, 1, 7, 10, noise);   // object 1 seen by node 2 too (25 points in all)
  addPoints(t2, f2, 2, 3, 11, noise);   // object 2: 11 of 12 in found 3: found whole
  addPoints(t2, f2, 2, -1, 1, noise);
  addPoints(t2, f2, 3, 8, 7, noise);    // object 3: 7 + 5 of 12 in two: found (7/12) and split
  addPoints(t2, f2, 3, 9, 5, noise);
  addPoints(t2, f2, 4, 10, 4, noise);   // object 4: 4 of 10 in one cluster: missed, not split
  addPoints(t2, f2, 4, -1, 6, noise);
  addPoints(t2, f2, 5, 11, 3, noise);   // object 5: 3 points, too small to count
  addPoints(t2, f2, -1, -1, 3, noise);
  EdgeView view;
  view.truth[1] = t1;
  view.truth[2] = t2;
  const PointObjects objects{{1, f1}, {2, f2}};

  const auto scores = scoreAgainstTruth(objects, view);
  ASSERT_TRUE(scores.ok()) << scores.error().message;
  EXPECT_EQ(scores->point_count, t1.size() + t2.size());
  EXPECT_EQ(scores->objects.objects_true, 5U);  // 0, 1, 2, 3, 4
  EXPECT_EQ(scores->objects.merged, 2U);        // 0 and 1
  EXPECT_EQ(scores->objects.found_whole, 1U);   // 2
  EXPECT_EQ(scores->objects.split, 1U);         // 3
  EXPECT_EQ(scores->objects.missed, 1U);        // 4

  std::vector<std::int64_t> truth = t1, found = f1;
  truth.insert(truth.end(), t2.begin(), t2.end());
  found.insert(found.end(), f2.begin(), f2.end());
  const RandScores want = bruteForceRand(found, truth);
  EXPECT_LT(want.rand_index, 1.0);
  EXPECT_NEAR(scores->points.rand_index, want.rand_index, 1e-12);
  EXPECT_NEAR(scores->points.adjusted_rand_index, want.adjusted_rand_index, 1e-12);
}

TEST(EvaluationScoreAgainstTruth, TruthlessPointsAreSingletonsNotOneCluster) {
  // Two ground points found together: the truth keeps them apart, so that pair disagrees.
  EdgeView view;
  view.truth[1] = {-1, -1, 0, 0};
  const PointObjects objects{{1, {5, 5, 6, 6}}};
  const auto scores = scoreAgainstTruth(objects, view);
  ASSERT_TRUE(scores.ok()) << scores.error().message;
  EXPECT_NEAR(scores->points.rand_index, 5.0 / 6.0, 1e-12);
  EXPECT_NEAR(scores->points.rand_index, bruteForceRand({5, 5, 6, 6}, {-1, -1, 0, 0}).rand_index, 1e-12);
}

TEST(EvaluationScoreAgainstTruth, AViewWithoutTruthIsAnError) {
  EdgeView view;
  view.local_labels[1] = {0, 0, -1};
  const PointObjects objects{{1, {0, 0, -1}}};
  const auto scores = scoreAgainstTruth(objects, view);
  ASSERT_FALSE(scores.ok());
  EXPECT_EQ(scores.error().code, ErrorCode::kInvalidArgument);
}

TEST(EvaluationScoreAgainstTruth, ObjectsNotCoveringTheTruthAreAnErrorNamingTheNode) {
  EdgeView view;
  view.truth[4] = {0, 0, 1};
  view.truth[9] = {1, 1, -1, -1};
  {
    const PointObjects objects{{4, {0, 0, 1}}, {9, {1, 1, -1}}};  // one label short on node 9
    const auto scores = scoreAgainstTruth(objects, view);
    ASSERT_FALSE(scores.ok());
    EXPECT_EQ(scores.error().code, ErrorCode::kInvalidArgument);
    EXPECT_TRUE(mentions(scores.error(), "node 9")) << scores.error().message;
    EXPECT_FALSE(mentions(scores.error(), "node 4")) << scores.error().message;
  }
  {
    const PointObjects objects{{9, {1, 1, -1, -2}}};  // node 4 missing
    const auto scores = scoreAgainstTruth(objects, view);
    ASSERT_FALSE(scores.ok());
    EXPECT_TRUE(mentions(scores.error(), "node 4")) << scores.error().message;
  }
}

// ---------------------------------------------------------------------------------------------
// ellipsoidPrecisionRecall

TEST(EvaluationEllipsoidPrecisionRecall, CoveringEllipsoidsOfSeparatedObjectsArePerfect) {
  const EdgeView view = twoBoxes();
  const auto pr = ellipsoidPrecisionRecall(view, kCoveringNoAura);
  EXPECT_EQ(pr.clusters, 2U);
  EXPECT_DOUBLE_EQ(pr.precision, 1.0);
  EXPECT_DOUBLE_EQ(pr.recall, 1.0);
  const auto want = bruteForcePrecisionRecall(view, kCoveringNoAura.alpha);
  EXPECT_EQ(want.clusters, 2U);
  EXPECT_DOUBLE_EQ(want.precision, 1.0);
  EXPECT_DOUBLE_EQ(want.recall, 1.0);
}

TEST(EvaluationEllipsoidPrecisionRecall, IntrudersInsideAnEllipsoidLowerItsPrecisionExactly) {
  EdgeView view = twoBoxes();
  // Four points of a third true object near the first box's centre, noise to the edge: they
  // change no ellipsoid but lie inside the first one.
  constexpr int kIntruders = 4;
  for (int i = 0; i < kIntruders; ++i) {
    view.points[1].push_back({0.4F + 0.05F * static_cast<float>(i), 0.45F, 0.55F, 0.0F});
    view.local_labels[1].push_back(-1);
    view.truth[1].push_back(11);
  }
  const auto pr = ellipsoidPrecisionRecall(view, kCoveringNoAura);
  EXPECT_EQ(pr.clusters, 2U);  // the intruders' object has no cluster
  const double first = kGridPoints / (kGridPoints + kIntruders);
  EXPECT_NEAR(pr.precision, (first + 1.0) / 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(pr.recall, 1.0);
  const auto want = bruteForcePrecisionRecall(view, kCoveringNoAura.alpha);
  EXPECT_NEAR(want.precision, (first + 1.0) / 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(want.recall, 1.0);
}

TEST(EvaluationEllipsoidPrecisionRecall, ATinyConfidenceStepLosesRecall) {
  const EdgeView view = twoBoxes();
  const auto pr = ellipsoidPrecisionRecall(view, {0.05, 0.0});
  // Semi-axes 0.05 * sqrt(0.125) ~ 0.018 m: only each box's centre point is inside.
  EXPECT_EQ(pr.clusters, 2U);
  EXPECT_LT(pr.recall, 0.2);
  EXPECT_NEAR(pr.recall, 1.0 / kGridPoints, 1e-12);
  EXPECT_DOUBLE_EQ(pr.precision, 1.0);
  const auto want = bruteForcePrecisionRecall(view, 0.05);
  EXPECT_NEAR(want.recall, 1.0 / kGridPoints, 1e-12);
}

TEST(EvaluationEllipsoidPrecisionRecall, ClustersOfNoTrueObjectAreNotCountedOnAnyNode) {
  EdgeView view = twoBoxes();
  // Node 1: a third cluster, of ground only (truth -1), far from the boxes.
  const Cloud ground = gridBox({20, 0, 0});
  view.points[1].insert(view.points[1].end(), ground.begin(), ground.end());
  view.local_labels[1].insert(view.local_labels[1].end(), 125, 2);
  view.truth[1].insert(view.truth[1].end(), 125, -1);
  // Node 2: a ground cluster and a cluster of object 7 (seen by node 1 too), both perfect.
  NodeScene two;
  two.add(gridBox({0, 5, 0}), 0, -1);
  two.add(gridBox({0, 0, 0}), 1, 7);
  putNode(view, 2, two);

  const auto pr = ellipsoidPrecisionRecall(view, kCoveringNoAura);
  EXPECT_EQ(pr.clusters, 3U);  // node 1's two boxes and node 2's object 7
  EXPECT_DOUBLE_EQ(pr.precision, 1.0);
  EXPECT_DOUBLE_EQ(pr.recall, 1.0);
}

TEST(EvaluationEllipsoidPrecisionRecall, AClusterMostlyOfNoObjectIsNotCounted) {
  // The contract counts clusters "whose points are mostly of a true object": a cluster of 125
  // ground points with 2 points of object 5 among them is ground left over, not object 5's.
  NodeScene scene;
  scene.add(gridBox({0, 0, 0}), 0, 7);
  scene.add(gridBox({10, 0, 0}), 1, -1);
  scene.add(Cloud{{10.6F, 0.4F, 0.5F, 0.0F}, {10.4F, 0.6F, 0.5F, 0.0F}}, 1, 5);
  EdgeView view;
  putNode(view, 1, scene);
  const auto pr = ellipsoidPrecisionRecall(view, kCoveringNoAura);
  EXPECT_EQ(pr.clusters, 1U);
  EXPECT_DOUBLE_EQ(pr.precision, 1.0);
  EXPECT_DOUBLE_EQ(pr.recall, 1.0);
}

TEST(EvaluationEllipsoidPrecisionRecall, AgreesWithFirstPrinciplesOnRandomOverlappingClusters) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_int_distribution<int> count(15, 60);
  for (int round = 0; round < 20; ++round) {
    EdgeView view;
    for (std::uint32_t node = 1; node <= 2; ++node) {
      NodeScene scene;
      // Five blobs whose boxes overlap, each mostly of one object with some points of others
      // and of none; a scatter of noise points of every kind.
      for (std::int32_t c = 0; c < 5; ++c) {
        const Eigen::Vector3d corner(3.0 * unit(rng), 3.0 * unit(rng), unit(rng));
        const Eigen::Vector3d size(0.5 + 2.0 * unit(rng), 0.5 + 2.0 * unit(rng), 0.3 + unit(rng));
        const int n = count(rng);
        for (int i = 0; i < n; ++i) {
          const Eigen::Vector3d p = corner + size.cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
          const double u = unit(rng);
          const std::int64_t object = u < 0.7 ? c : (u < 0.85 ? (c + 1) % 5 : -1);
          scene.add(Cloud{{static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.0F}},
                    c, object);
        }
      }
      for (int i = 0; i < 40; ++i) {
        const Eigen::Vector3d p(4.0 * unit(rng), 4.0 * unit(rng), 1.5 * unit(rng));
        scene.add(Cloud{{static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.0F}},
                  -1, static_cast<std::int64_t>(i % 6) - 1);
      }
      putNode(view, node, scene);
    }
    const double alpha = 0.8 + 1.6 * unit(rng);
    const auto pr = ellipsoidPrecisionRecall(view, {alpha, 0.0});
    const auto want = bruteForcePrecisionRecall(view, alpha);
    ASSERT_EQ(want.clusters, 10U);
    EXPECT_EQ(pr.clusters, want.clusters) << "round " << round;
    EXPECT_NEAR(pr.precision, want.precision, 1e-12) << "round " << round;
    EXPECT_NEAR(pr.recall, want.recall, 1e-12) << "round " << round;
    EXPECT_GT(want.precision, 0.0);
    EXPECT_LT(want.recall, 1.0);
  }
}

}  // namespace
}  // namespace fogmap::harness
