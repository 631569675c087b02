#pragma once
// Scoring a cluster's output against the truth of a simulated scene (the evaluation of the MAD-C
// paper, Figs. 6 to 8): the global object of every point, point-level Rand indices and
// object-level counts against the true objects, and the precision and recall of the edges'
// bounding ellipsoids. Pure: views and published maps in, numbers out.
#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "common/base/status.hpp"
#include "common/geometry/ellipsoid.hpp"
#include "common/io/messages.hpp"
#include "common/scoring/object_match.hpp"
#include "common/scoring/rand_index.hpp"
#include "harness/cluster_run.hpp"

namespace fogmap::harness {

// Per node of the view, the object of every point (the view's order); negative: noise, each
// negative value used once (a singleton in the Rand index).
using PointObjects = std::map<std::uint32_t, std::vector<std::int64_t>>;

// MAD-C's global objects: a point belongs to the global object holding its local cluster's
// ellipsoid in `madc` (MAD-C-ext's per-point labels).
PointObjects madcPointObjects(const GlobalMapMessage& madc, const EdgeView& view);
// The baseline's central clustering (its point labels); an error when they do not cover the view.
Expected<PointObjects> baselinePointObjects(const GlobalMapMessage& baseline, const EdgeView& view);

struct TruthScores {
  RandScores points;    // over every point of the view (points of no true object: singletons)
  ObjectMatch objects;  // true objects found whole, split, merged, missed
  std::vector<ObjectOutcome> outcomes;  // the same per true object (objects = countOutcomes(outcomes))
  std::size_t point_count = 0;
};
// Errors when the view has no truth or `objects` does not cover it.
Expected<TruthScores> scoreAgainstTruth(const PointObjects& objects, const EdgeView& view,
                                        const ObjectMatchParams& params = {});

// The paper's ellipsoid precision and recall, against the truth: for every local cluster whose
// points are mostly of a true object, precision = points of the edge inside its ellipsoid that are
// of that object / all points of the edge inside it (0 when it covers none), recall = those
// points / the edge's points of the object. Averaged over those clusters of every node.
struct PrecisionRecall {
  double precision = 0.0;
  double recall = 0.0;
  std::size_t clusters = 0;
};
PrecisionRecall ellipsoidPrecisionRecall(const EdgeView& view, const EllipsoidParams& params);

}  // namespace fogmap::harness
